// kinematics.hpp - forward and inverse kinematics of the RBX1 for top-down grasps, and the joint limit check.
// Convention (README "Kinematics"): all joints zero = arm straight up; chain
// Rz(q1) Tz(base_height) Ry(q2) Tz(upper_arm) Ry(q3) Tz(forearm) Rz(q4) Ry(q5) Tz(tool) Rz(q6).
#pragma once
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "arm_config.hpp"

namespace rbx1::arm {

// The tool frame in the arm base frame, translation in mm: z along the fingers (away from the wrist),
// x along the fingers' closing line.
Eigen::Isometry3d fk(const Links& links, const Joints& deg);

// The tool frame read as a grasp: tool point, the closing line's yaw in the table plane folded into (-90, 90]
// (the gripper is symmetric under 180 deg), and tilt = angle between the tool axis and straight down.
struct ToolPose {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double yaw_deg = 0, tilt_deg = 0;
};
ToolPose tool_pose(const Links& links, const Joints& deg);

// A top-down grasp: tool point in the base frame (mm) and the closing line's direction (deg, from +x towards +y).
struct Grasp {
  double x_mm = 0, y_mm = 0, z_mm = 0, yaw_deg = 0;
};

struct IkSolution {
  Joints joints{};
  bool elbow_up = true;        // elbow above the line from the shoulder to the wrist
  bool wrist_flipped = false;  // forearm rolled half a turn (J4 = +-180) and the wrist pitched the other way
  bool reaches_back = false;   // base turned half a turn away from the target, the arm leaning back over it
  std::string limit_error;     // empty when every joint is within its limits
};

// Every top-down solution (2 base branches x elbow up/down x wrist flip), each joint folded to the equivalent
// angle (J1, J4 mod 360; J6 mod 180) within its limits nearest `current`, sorted best first: elbow up, then
// unflipped, then nearest to `current` (sum of squared joint differences). false + error when out of reach.
bool ik_solutions(const ArmConfig& cfg, const Grasp& target, const Joints& current, std::vector<IkSolution>& out,
                  std::string& error);

// The chosen solution: the first of ik_solutions that is elbow up and within the limits. Elbow-down solutions are
// never taken (they drive the elbow towards the table). false + error naming the joint and its limit, or the reach.
bool ik(const ArmConfig& cfg, const Grasp& target, const Joints& current, Joints& out, std::string& error);

// false + "J5 (wrist pitch) at 130 deg is above its limit max_deg = 115 (arm.joints.j5.max_deg)" for the first
// joint outside its limits.
bool check_limits(const ArmConfig& cfg, const Joints& deg, std::string& error);

double normalize_deg(double deg);       // into (-180, 180]
double normalize_axis_deg(double deg);  // into (-90, 90]: a direction without sense, like the closing line

}  // namespace rbx1::arm
