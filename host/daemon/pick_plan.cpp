// pick_plan.cpp - vision::ScanObject -> arm::PickObject -> arm::plan_pick waypoints -> MotionStep queue entries.
#include "pick_plan.hpp"

#include <cmath>

#include "kinematics.hpp"
#include "pick.hpp"
#include "vision_map.hpp"

namespace rbx1::daemon {

// The arm model's joints are the wire's joints, one for one.
static_assert(arm::kJoints == RBX1_JOINTS, "host/arm kJoints differs from messages.json's joints");

namespace {
arm::Steps steps_of(const rbx1_status_resp& s) {
  arm::Steps out;
  for (int i = 0; i < RBX1_JOINTS; ++i) out[i] = s.position[i];
  return out;
}

MotionStep to_step(const arm::Waypoint& w) {
  MotionStep s;
  s.name = w.name;
  s.gripper = w.kind == arm::WaypointKind::Gripper;
  for (int i = 0; i < RBX1_JOINTS; ++i) s.target[i] = w.steps[i];
  s.duration_ms = w.duration_ms;
  s.pulse_us = w.pulse_us;
  s.dwell_ms = w.dwell_ms;
  return s;
}

double round2(double v) { return std::round(v * 100) / 100; }
}  // namespace

bool plan_pose_move(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const std::string& name,
                    const arm::Joints& pose, std::vector<MotionStep>& out, std::string& error) {
  arm::Waypoint w;
  if (!arm::plan_move(cfg, name, steps_of(current), pose, w, error)) return false;
  out = {to_step(w)};
  return true;
}

std::optional<Eigen::Vector2d> table_point(const arm::ArmConfig& cfg, cv::Point2d px, std::optional<cv::Point2d> cm) {
  if (cfg.camera.pixel_map) {
    const Eigen::Vector2d p(px.x, px.y);
    double opening = 0;
    const arm::TablePoint t = arm::pixels_to_base(cfg, p, p, p, opening);
    return Eigen::Vector2d(t.x_mm, t.y_mm);
  }
  if (!cm) return std::nullopt;
  const arm::TablePoint t = arm::vision_to_base(cfg, {cm->x, cm->y}, 0);
  return Eigen::Vector2d(t.x_mm, t.y_mm);
}

bool look_pose(const arm::ArmConfig& cfg, const Eigen::Vector2d& shift, arm::Joints& out, std::string& error) {
  const arm::ToolPose scan = arm::tool_pose(cfg.links, cfg.scan);
  const arm::Grasp over{scan.x_mm + shift.x(), scan.y_mm + shift.y(), scan.z_mm, scan.yaw_deg};
  return arm::ik(cfg, over, cfg.scan, out, error);
}

bool plan_pick_steps(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const vision::ScanObject& object,
                     cv::Size image_size, const std::string& place, std::vector<MotionStep>& out, nlohmann::json& info,
                     std::string& error) {
  const vision::Grip& grip = object.grip;
  if (!object.centroid_cm || !grip.opening_cm) {
    error = "the detection has no table coordinates (vision is uncalibrated: set [vision] px_per_cm or calibration)";
    return false;
  }
  if (!grip.feasible) {
    error = "no feasible grip (opening " + std::to_string(*grip.opening_cm) + " cm)";
    return false;
  }
  arm::PickObject obj;
  if (cfg.camera.pixel_map) {
    // The workspace calibration: straight from the image's pixels to the base frame.
    auto px = [](cv::Point2d p) { return Eigen::Vector2d(p.x, p.y); };
    const auto& m = *cfg.camera.pixel_map;
    if (image_size.width != m.width || image_size.height != m.height) {
      error = "the workspace calibration is for " + std::to_string(m.width) + "x" + std::to_string(m.height) +
              " frames, the camera gives " + std::to_string(image_size.width) + "x" + std::to_string(image_size.height) +
              " (rbx1 calibrate-workspace again)";
      return false;
    }
    arm::TablePoint p = arm::pixels_to_base(cfg, px(object.centroid_px), px(grip.p1), px(grip.p2), obj.opening_mm);
    obj.x_mm = p.x_mm;
    obj.y_mm = p.y_mm;
    obj.yaw_deg = p.yaw_deg;
  } else {
    arm::TablePoint p = arm::vision_to_base(cfg, {object.centroid_cm->x, object.centroid_cm->y}, grip.angle_deg);
    obj.x_mm = p.x_mm;
    obj.y_mm = p.y_mm;
    obj.yaw_deg = p.yaw_deg;
    obj.opening_mm = *grip.opening_cm * 10.0;
  }
  std::vector<arm::Waypoint> waypoints;
  if (!arm::plan_pick(cfg, steps_of(current), obj, place, waypoints, error)) return false;
  out.clear();
  nlohmann::json wj = nlohmann::json::array();
  for (const auto& w : waypoints) {
    out.push_back(to_step(w));
    nlohmann::json j{{"name", w.name}, {"kind", arm::kind_name(w.kind)}};
    if (w.kind == arm::WaypointKind::Gripper) {
      j["pulse_us"] = w.pulse_us;
      j["dwell_ms"] = w.dwell_ms;
    } else {
      j["target"] = w.steps;
      j["duration_ms"] = w.duration_ms;
      // Where the tool point will be (the console draws the planned path before it runs).
      Eigen::Vector3d tool = arm::fk(cfg.links, w.joints).translation();
      j["tool_mm"] = {round2(tool.x()), round2(tool.y()), round2(tool.z())};
    }
    wj.push_back(j);
  }
  info = {{"grasp", {{"x_mm", round2(obj.x_mm)}, {"y_mm", round2(obj.y_mm)}, {"yaw_deg", round2(obj.yaw_deg)},
                     {"opening_mm", round2(obj.opening_mm)}}},
          {"map", cfg.camera.pixel_map ? "workspace" : "mount"},
          {"place", place},
          {"waypoints", wj}};
  return true;
}

}  // namespace rbx1::daemon
