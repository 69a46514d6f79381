// arm_config.hpp - the [arm] settings: link lengths, joints, gripper, poses, camera mount, places, heights, speeds.
// Every value has a documented default (host/arm/defaults.toml is the same set written out) and a range.
#pragma once
#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "config.hpp"

namespace rbx1::arm {

constexpr int kJoints = 6;
using Joints = std::array<double, kJoints>;  // joint angles in degrees, J1..J6 (README: convention)
using Steps = std::array<int32_t, kJoints>;  // absolute step counts as on the wire

// Lengths of the kinematic chain (README diagram). Defaults follow the community RBX1 URDF; measure yours.
struct Links {
  double base_height_mm = 263.0;  // table surface under the base to the shoulder axis
  double upper_arm_mm = 221.0;    // shoulder axis to elbow axis
  double forearm_mm = 215.0;      // elbow axis to wrist-pitch axis (forearm roll turns about this line)
  double tool_mm = 120.0;         // wrist-pitch axis to the tool point (centre between the fingertips)
  bool operator==(const Links&) const = default;
};

// One stepper joint: angle <-> steps and the allowed range (host/arm/README.md: rounding rules).
struct JointConfig {
  double reduction = 1.0;  // motor turns per joint turn
  int motor_steps = 200;   // full steps per motor turn
  int microsteps = 16;
  double min_deg = -180.0, max_deg = 180.0;
  int direction = 1;       // +1: positive angle = positive steps; -1: reversed
  double zero_deg = 0.0;   // joint angle at step count 0 (where homing puts HOME_POSITION)
  // The firmware's limits of this joint (its MAX_SPEED and ACCEL keys, PROTOCOL.md): straight lines are timed
  // against them (line_timing.hpp), so they must match what the board has (the defaults are the firmware's).
  int max_speed_steps_s = 4000;
  int accel_steps_s2 = 8000;
  bool operator==(const JointConfig&) const = default;
};

// Hobby-servo two-finger gripper: pulse width is linear in the opening between closed and fully open.
struct GripperConfig {
  int closed_us = 1000;          // pulse for fingers touching (opening 0)
  int open_us = 2000;            // pulse for the widest opening
  double max_opening_mm = 50.0;  // opening at open_us
  double margin_mm = 5.0;        // opened this much wider than the object before descending
  double finger_depth_mm = 15.0; // how far the finger pads reach up from the tool point
  int dwell_ms = 500;            // time the servo gets to move before the next queue entry
  bool operator==(const GripperConfig&) const = default;
};

// Where the vision table frame (cm; x right, y down in the image; angles from +x towards +y) lies in the
// arm base frame when the arm is at the scan pose: base = origin + R(rotation) * F * 10 * p_cm,
// F = diag(1, -1) when flip_y (an image seen from above is mirrored), else identity.
struct CameraMount {
  double origin_x_mm = 370.0, origin_y_mm = 100.0;  // base-frame position of the vision frame's origin
  double rotation_deg = -90.0;                      // from base +x towards base +y
  bool flip_y = true;
  // The workspace calibration in force (rbx1 calibrate-workspace, from the daemon's state directory): undistorted
  // image pixel -> base mm at table height, row-major 3x3, for frames of width x height. When set, it replaces
  // origin, rotation and flip (vision_map.hpp).
  struct PixelMap {
    std::array<double, 9> h{};
    int width = 0, height = 0;
    bool operator==(const PixelMap&) const = default;
  };
  std::optional<PixelMap> pixel_map;
  bool operator==(const CameraMount&) const = default;
};

// A named place to put objects: the surface height there and the gripper yaw at release.
struct Place {
  double x_mm = 0, y_mm = 0, z_mm = 0, yaw_deg = 0;
  bool operator==(const Place&) const = default;
};

struct Heights {
  double table_z_mm = 0.0;              // table surface in the base frame
  double approach_clearance_mm = 40.0;  // tool above the object's top before descending / after release
  double lift_clearance_mm = 60.0;      // object's bottom above its own height (lift) or the place surface (carry)
  double finger_clearance_mm = 2.0;     // fingertips never go lower than this above the table
  bool operator==(const Heights&) const = default;
};

struct Speeds {
  double joint_speed_deg_s = 20.0;  // the joint that moves furthest sets a move's duration
  int min_move_ms = 200;            // no move is planned shorter than this
  bool operator==(const Speeds&) const = default;
};

// A default-constructed ArmConfig holds the documented defaults.
struct ArmConfig {
  Links links;
  // Reductions: the published community set; limits: the RBX1 community driver's joint limits.
  std::array<JointConfig, kJoints> joints{{
      {10.67, 200, 16, -120.0, 120.0, 1, 0.0},  // J1 base yaw
      {5.0, 200, 16, -105.0, 105.0, 1, 0.0},    // J2 shoulder
      {21.5, 200, 16, -120.0, 120.0, 1, 0.0},   // J3 elbow
      {1.0, 200, 16, -180.0, 180.0, 1, 0.0},    // J4 forearm roll
      {4.67, 200, 16, -115.0, 115.0, 1, 0.0},   // J5 wrist pitch
      {1.0, 200, 16, -180.0, 180.0, 1, 0.0},    // J6 wrist roll
  }};
  GripperConfig gripper;
  Joints home{0, 0, 0, 0, 0, 0};      // arm straight up
  Joints scan{0, 20, 60, 0, 100, 0};  // tool (and camera) straight down at about (287, 0, 388) mm
  CameraMount camera;
  std::map<std::string, Place> places{{"tray", Place{150.0, 250.0, 5.0, 0.0}}};
  Heights heights;
  Speeds speeds;
  bool operator==(const ArmConfig&) const = default;
};

// The built-in defaults (the same values host/arm/defaults.toml writes out).
ArmConfig default_arm_config();

// Reads the [arm] table and its subtables into out, starting from the defaults. Range, type, unknown-key and
// consistency problems go to arm.errors(), each naming its key ("arm.joints.j3.max_deg: ..."). Returns true
// when this call added no error; out is filled either way (a bad value keeps its default).
bool parse_arm_config(rbx1::config::Section arm, ArmConfig& out);

// "base yaw", "shoulder", "elbow", "forearm roll", "wrist pitch", "wrist roll" for j = 0..5.
const char* joint_name(int j);

}  // namespace rbx1::arm
