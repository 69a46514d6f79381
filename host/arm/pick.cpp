// pick.cpp - plans the pick sequence: the heights of each stage, IK per stage (straight lines split by line.hpp),
// timing and servo pulses.
#include "pick.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "line.hpp"
#include "line_timing.hpp"

namespace rbx1::arm {

namespace {

std::string mm(double v, int decimals = 1) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// Appends the move to `to` after the last waypoint; the arm's position after rounding to steps is what
// the next stage starts from.
bool add_move(const ArmConfig& cfg, std::vector<Waypoint>& out, const std::string& name, const Steps& from,
              const Joints& to, std::string& error) {
  Waypoint w;
  if (!plan_move(cfg, name, from, to, w, error)) return false;
  out.push_back(w);
  return true;
}

void add_gripper(const ArmConfig& cfg, std::vector<Waypoint>& out, const std::string& name, const Steps& at,
                 uint16_t pulse_us) {
  Waypoint w;
  w.name = name;
  w.kind = WaypointKind::Gripper;
  w.steps = at;
  w.joints = steps_to_joints(cfg, at);
  w.pulse_us = pulse_us;
  w.dwell_ms = uint16_t(cfg.gripper.dwell_ms);
  out.push_back(w);
}

// Appends the straight line of the tool point from where the arm stands (`at`, read by FK) to `to`, split by
// plan_line and timed by time_line: one move named `name` per segment, the line one profile within the joints'
// limits, no faster than a joint move over the same travel (the firmware's look-ahead joins the segments).
bool add_line(const ArmConfig& cfg, std::vector<Waypoint>& out, const std::string& name, Steps& at, const Grasp& to,
              std::string& error) {
  const ToolPose p = tool_pose(cfg.links, steps_to_joints(cfg, at));
  const Grasp from{p.x_mm, p.y_mm, p.z_mm, p.yaw_deg};
  std::vector<Steps> targets;
  std::string why;
  if (!plan_line(cfg, at, from, to, LineBounds{}, targets, why)) {
    error = name + ": " + why;
    return false;
  }
  // A target equal to the one before would be a zero-length MOVE: a stop in the middle of the line.
  targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
  if (!targets.empty() && targets.front() == at) targets.erase(targets.begin());
  LineTiming timing;
  if (!time_line(cfg, at, targets, timing, why)) {
    error = name + ": " + why;
    return false;
  }
  for (size_t k = 0; k < targets.size(); ++k) {
    Waypoint w;
    w.name = name;
    w.kind = WaypointKind::Move;
    w.steps = targets[k];
    w.joints = steps_to_joints(cfg, targets[k]);
    if (!check_limits(cfg, w.joints, why)) {
      error = name + ": " + why;
      return false;
    }
    w.duration_ms = timing.duration_ms[k];
    out.push_back(w);
    at = targets[k];
  }
  return true;
}

}  // namespace

int64_t segment_ms(const ArmConfig& cfg, const Joints& from, const Joints& to) {
  double largest = 0;
  for (int j = 0; j < kJoints; ++j) largest = std::max(largest, std::fabs(to[j] - from[j]));
  int64_t ms = int64_t(std::ceil(1000.0 * largest / cfg.speeds.joint_speed_deg_s - 1e-9));
  return std::max<int64_t>(ms, 1);
}

const char* kind_name(WaypointKind kind) { return kind == WaypointKind::Move ? "move" : "gripper"; }

Steps home_steps(const ArmConfig& cfg) { return joints_to_steps(cfg, cfg.home); }
Steps scan_steps(const ArmConfig& cfg) { return joints_to_steps(cfg, cfg.scan); }

bool gripper_pulse_us(const GripperConfig& g, double opening_mm, uint16_t& pulse_us, std::string& error) {
  if (!std::isfinite(opening_mm) || opening_mm < 0.0) {
    error = std::isfinite(opening_mm) ? "gripper opening " + mm(opening_mm) + " mm is negative"
                                      : "gripper opening is not a finite number";
    return false;
  }
  if (opening_mm > g.max_opening_mm + 1e-9) {
    const int d = mm(opening_mm) == mm(g.max_opening_mm) ? 2 : 1;  // "50.0 is wider than 50.0" would say nothing
    error = "gripper opening " + mm(opening_mm, d) + " mm is wider than the gripper's " + mm(g.max_opening_mm, d) +
            " mm (arm.gripper.max_opening_mm)";
    return false;
  }
  double us = g.closed_us + (g.open_us - g.closed_us) * opening_mm / g.max_opening_mm;
  pulse_us = uint16_t(std::lround(us));
  return true;
}

int64_t move_duration_ms(const ArmConfig& cfg, const Joints& from, const Joints& to) {
  return std::max<int64_t>(segment_ms(cfg, from, to), cfg.speeds.min_move_ms);
}

bool plan_move(const ArmConfig& cfg, const std::string& name, const Steps& from, const Joints& to, Waypoint& out,
               std::string& error) {
  std::string why;
  if (!check_limits(cfg, to, why)) {
    error = name + ": " + why;
    return false;
  }
  Waypoint w;
  w.name = name;
  w.kind = WaypointKind::Move;
  w.steps = joints_to_steps(cfg, to);
  w.joints = steps_to_joints(cfg, w.steps);
  int64_t ms = move_duration_ms(cfg, steps_to_joints(cfg, from), w.joints);
  if (ms > 65535) {
    error = name + ": the move would take " + std::to_string(ms) +
            " ms, more than MOVE allows (65535); raise arm.speeds.joint_speed_deg_s";
    return false;
  }
  w.duration_ms = uint16_t(ms);
  out = w;
  return true;
}

bool plan_pick(const ArmConfig& cfg, const Steps& current, const PickObject& obj, const std::string& place_name,
               std::vector<Waypoint>& out, std::string& error, bool lines) {
  out.clear();
  auto place_it = cfg.places.find(place_name);
  if (place_it == cfg.places.end()) {
    std::string known;
    for (const auto& [name, p] : cfg.places) known += (known.empty() ? "" : ", ") + name;
    error = "unknown place '" + place_name + "' (arm.places has: " + (known.empty() ? "none" : known) + ")";
    return false;
  }
  const Place& place = place_it->second;
  if (!std::isfinite(obj.height_mm) || obj.height_mm < 0.0) {
    error = std::isfinite(obj.height_mm) ? "object height " + mm(obj.height_mm) + " mm is negative"
                                         : "object height is not a finite number";
    return false;
  }
  uint16_t open_us = 0, closed_us = 0;
  if (!gripper_pulse_us(cfg.gripper, obj.opening_mm, open_us, error)) return false;  // the object must fit
  // Open wider than the object by the margin, but never past the gripper's widest opening.
  const double open_mm = std::min(obj.opening_mm + cfg.gripper.margin_mm, cfg.gripper.max_opening_mm);
  gripper_pulse_us(cfg.gripper, open_mm, open_us, error);
  gripper_pulse_us(cfg.gripper, 0.0, closed_us, error);

  // Heights of the tool point (README "Pick sequence").
  const Heights& h = cfg.heights;
  const double grasp_above = std::max(obj.height_mm - cfg.gripper.finger_depth_mm, h.finger_clearance_mm);
  const double grasp_z = h.table_z_mm + grasp_above;
  const double approach_z = h.table_z_mm + obj.height_mm + h.approach_clearance_mm;
  const double lift_z = grasp_z + obj.height_mm + h.lift_clearance_mm;
  const double carry_z = place.z_mm + grasp_above + h.lift_clearance_mm;
  const double retreat_z = carry_z + h.approach_clearance_mm;

  Steps at = current;
  auto ik_move = [&](const std::string& name, const Grasp& g, bool keep_roll) {
    Joints now = steps_to_joints(cfg, at), q{};
    std::string why;
    if (!ik(cfg, g, now, q, why)) {
      error = name + ": " + why;
      return false;
    }
    if (keep_roll) q[5] = now[5];  // approach first, turn the wrist on the spot
    if (!add_move(cfg, out, name, at, q, error)) return false;
    at = out.back().steps;
    return true;
  };

  // Approach: a straight line when the arm points down (the scan pose), keeping the tool's yaw; the wrist turns
  // on the spot after. From any other pose a joint move keeping J6. Descend, lift and retreat are straight lines.
  const ToolPose now = tool_pose(cfg.links, steps_to_joints(cfg, at));
  const Grasp above{obj.x_mm, obj.y_mm, approach_z, obj.yaw_deg};
  if (now.tilt_deg <= LineBounds{}.tilt_deg && lines) {
    if (!add_line(cfg, out, "approach", at, Grasp{above.x_mm, above.y_mm, above.z_mm, now.yaw_deg}, error))
      return false;
  } else if (!ik_move("approach", above, true)) {
    return false;
  }
  if (!ik_move("yaw", above, false)) return false;
  add_gripper(cfg, out, "open", at, open_us);
  auto line = [&](const std::string& name, const Grasp& g) {
    return lines ? add_line(cfg, out, name, at, g, error) : ik_move(name, g, false);
  };
  if (!line("descend", Grasp{obj.x_mm, obj.y_mm, grasp_z, obj.yaw_deg})) return false;
  add_gripper(cfg, out, "close", at, closed_us);
  if (!line("lift", Grasp{obj.x_mm, obj.y_mm, lift_z, obj.yaw_deg})) return false;
  if (!ik_move("carry", Grasp{place.x_mm, place.y_mm, carry_z, place.yaw_deg}, false)) return false;
  add_gripper(cfg, out, "release", at, open_us);
  if (!line("retreat", Grasp{place.x_mm, place.y_mm, retreat_z, place.yaw_deg})) return false;
  if (!add_move(cfg, out, "home", at, cfg.home, error)) return false;
  return true;
}

}  // namespace rbx1::arm
