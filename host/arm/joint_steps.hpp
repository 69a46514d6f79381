// joint_steps.hpp - joint angles (degrees) <-> absolute step counts through reduction and microstepping.
// Rule (README "Steps"): steps = round(direction * (angle - zero_deg) * motor_steps * microsteps * reduction / 360),
// rounding to nearest with halves away from zero; the reverse is exact division, so steps -> angle -> steps is
// the identity and angle -> steps -> angle is off by at most half a step.
#pragma once
#include "arm_config.hpp"

namespace rbx1::arm {

// Steps per joint revolution: motor_steps * microsteps * reduction (not an integer for 10.67 or 4.67).
double steps_per_rev(const JointConfig& j);
int32_t angle_to_steps(const JointConfig& j, double deg);
double steps_to_angle(const JointConfig& j, int32_t steps);

Steps joints_to_steps(const ArmConfig& cfg, const Joints& deg);
Joints steps_to_joints(const ArmConfig& cfg, const Steps& steps);

}  // namespace rbx1::arm
