// pick.hpp - the pick of the paper as firmware queue entries: approach, yaw, open, descend, close, lift, carry,
// release, retreat, home. Moves are absolute step targets; gripper entries are servo pulses. The approach (from a
// pose pointing down), descend, lift and retreat are straight lines of the tool point, one move per segment, all
// named after their phase.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "arm_config.hpp"

namespace rbx1::arm {

// The object to pick, in the arm base frame (vision_to_base gives x, y and yaw).
struct PickObject {
  double x_mm = 0, y_mm = 0;
  double yaw_deg = 0;     // the fingers' closing line (grip.angle_deg mapped to the base frame)
  double opening_mm = 0;  // the object's width along the closing line (grip.opening_cm * 10)
  double height_mm = 0;   // the object's top above the table (0 when unknown: grasp just above the table)
};

enum class WaypointKind { Move, Gripper };

struct Waypoint {
  std::string name;
  WaypointKind kind = WaypointKind::Move;
  Steps steps{};             // Move: the absolute target (MOVE.target); Gripper: where the arm stands meanwhile
  Joints joints{};           // steps in degrees (what the arm reaches after rounding to steps)
  uint16_t duration_ms = 0;  // Move: MOVE.duration_ms
  uint16_t pulse_us = 0;     // Gripper: GRIPPER.pulse_us
  uint16_t dwell_ms = 0;     // Gripper: GRIPPER.dwell_ms
};

// "move" or "gripper".
const char* kind_name(WaypointKind kind);

// The whole pick from the arm's current steps to home, for the named place (arm.places). false + error for an
// unknown place, an opening wider than the gripper, or a waypoint out of reach or limits (the error starts with
// the waypoint's name: "descend: target (...) mm is out of reach: ..."). lines = false plans every phase as one
// joint move (the pick before straight lines: tools/bench/motion compares the two).
bool plan_pick(const ArmConfig& cfg, const Steps& current, const PickObject& object, const std::string& place,
               std::vector<Waypoint>& out, std::string& error, bool lines = true);

// One joint move from `from` to the pose `to` (degrees), timed by move_duration_ms: for going to scan or home.
// false + error when `to` is outside the joint limits or the move would outlast MOVE.duration_ms (65535 ms).
bool plan_move(const ArmConfig& cfg, const std::string& name, const Steps& from, const Joints& to, Waypoint& out,
               std::string& error);

Steps home_steps(const ArmConfig& cfg);
Steps scan_steps(const ArmConfig& cfg);

// Opening (mm) -> servo pulse: closed_us + (open_us - closed_us) * opening / max_opening_mm, rounded to the
// nearest microsecond. false + error for an opening below 0 or above max_opening_mm.
bool gripper_pulse_us(const GripperConfig& g, double opening_mm, uint16_t& pulse_us, std::string& error);

// ceil(1000 * largest joint change / joint_speed_deg_s) ms, at least 1.
int64_t segment_ms(const ArmConfig& cfg, const Joints& from, const Joints& to);
// segment_ms, at least min_move_ms (may exceed 65535: check).
int64_t move_duration_ms(const ArmConfig& cfg, const Joints& from, const Joints& to);

}  // namespace rbx1::arm
