// line.hpp - straight lines of the tool point in the base frame, split into short joint moves with IK: between
// consecutive targets the firmware moves linearly in steps, and the tool point of that path stays within the stated
// bounds of the line (position and yaw of the closing line).
#pragma once
#include <string>
#include <vector>

#include "arm_config.hpp"
#include "kinematics.hpp"

namespace rbx1::arm {

// The bounds every straight line is planned to (README "Straight lines").
struct LineBounds {
  double deviation_mm = 0.2;  // tool point from the line
  double yaw_deg = 0.5;       // closing line from the yaw interpolated along the line
  double tilt_deg = 0.5;      // tool axis from straight down
};

// How far the joint-linear path between step targets a and b strays: sampled at `samples` points of each
// segment (ends included), against the line p0 -> p1 with the yaw interpolated from yaw0 to yaw1 by the
// projection of the sample onto the line.
struct LineError {
  double deviation_mm = 0, yaw_deg = 0, tilt_deg = 0;
};
LineError line_error(const ArmConfig& cfg, const Steps& a, const Steps& b, const Grasp& from, const Grasp& to,
                     int samples);

// Splits the straight line from `from` to `to` (top-down grasps) into step targets, the first move starting at
// `start` (which must be the IK of `from` rounded to steps) and the last one ending at the IK of `to`. Segments
// are halved until line_error() of each is within bounds, then on both sides of junctions where the firmware's
// junction rule is ruled by a joint's velocity jump (README, Straight lines). false + error (out of reach or
// limits on the way, naming the point, or a segment that no split brings within bounds).
bool plan_line(const ArmConfig& cfg, const Steps& start, const Grasp& from, const Grasp& to, const LineBounds& bounds,
               std::vector<Steps>& out, std::string& error);

}  // namespace rbx1::arm
