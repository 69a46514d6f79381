// urdf.hpp - the arm's robot description (URDF) written from the same [arm] table the kinematics read.
// Frames and names (README "Robot description"): base_link on the table under the base axis; revolute joints
// joint_1..joint_6 with the chain of kinematics.hpp; tool0 at the tool point (the frame fk() returns); the fingers
// as prismatic finger_left_joint (+x of tool0, metres from the centre) and finger_right_joint (its mimic);
// camera_optical (REP-103 optical: z out of the lens, x image right, y image down) fixed on tool0 so that at the
// scan pose it has the orientation of [arm.camera] and sits at the tool point. Metres and radians (REP-103).
#pragma once
#include <array>
#include <string>

#include "arm_config.hpp"

namespace rbx1::arm {

// The URDF joint names of J1..J6, and the gripper's (half the opening, metres).
extern const std::array<const char*, kJoints> kUrdfJointNames;
inline constexpr const char* kUrdfFingerJoint = "finger_left_joint";

// The whole URDF document (XML text, ending with a newline).
std::string urdf(const ArmConfig& cfg);

// The finger joint's position (metres from the centre) for a servo pulse: the inverse of gripper_pulse_us,
// clamped to [0, max_opening_mm / 2].
double finger_position_m(const GripperConfig& g, int pulse_us);

}  // namespace rbx1::arm
