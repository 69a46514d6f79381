// joint_steps.cpp - the angle <-> step conversion with its one rounding rule.
#include "joint_steps.hpp"

#include <cmath>

namespace rbx1::arm {

double steps_per_rev(const JointConfig& j) { return double(j.motor_steps) * j.microsteps * j.reduction; }

int32_t angle_to_steps(const JointConfig& j, double deg) {
  // std::llround rounds halves away from zero; the config ranges keep the result within int32.
  return int32_t(std::llround(j.direction * (deg - j.zero_deg) * steps_per_rev(j) / 360.0));
}

double steps_to_angle(const JointConfig& j, int32_t steps) {
  return j.zero_deg + j.direction * double(steps) * 360.0 / steps_per_rev(j);
}

Steps joints_to_steps(const ArmConfig& cfg, const Joints& deg) {
  Steps s{};
  for (int i = 0; i < kJoints; ++i) s[i] = angle_to_steps(cfg.joints[i], deg[i]);
  return s;
}

Joints steps_to_joints(const ArmConfig& cfg, const Steps& steps) {
  Joints q{};
  for (int i = 0; i < kJoints; ++i) q[i] = steps_to_angle(cfg.joints[i], steps[i]);
  return q;
}

}  // namespace rbx1::arm
