// scene.cpp - the `scene` request's result (scene.hpp): the pick's maps applied to the last scan and its frame.
#include "scene.hpp"

#include <cmath>
#include <optional>

#include "kinematics.hpp"
#include "urdf.hpp"
#include "vision_map.hpp"

namespace rbx1::daemon {

namespace {

using json = nlohmann::json;

double r2(double v) { return std::round(v * 100) / 100; }
Eigen::Vector2d px(const json& v) { return {v[0].get<double>(), v[1].get<double>()}; }
bool is_point(const json& v) { return v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number(); }

// The frame the scan saw, (width, height); none before a scan unless the workspace calibration names it.
std::optional<Eigen::Vector2i> frame_size(const arm::ArmConfig& arm, const json& detections) {
  if (detections.is_object() && detections.contains("image"))
    return Eigen::Vector2i(detections["image"].value("width", 0), detections["image"].value("height", 0));
  if (arm.camera.pixel_map) return Eigen::Vector2i(arm.camera.pixel_map->width, arm.camera.pixel_map->height);
  return std::nullopt;
}

// An image pixel on the table through the map in force; none when the mount map has no scale.
std::optional<Eigen::Vector2d> pixel_on_table(const arm::ArmConfig& arm, const Eigen::Vector2d& p, double px_per_cm) {
  if (arm.camera.pixel_map) {
    double unused;
    arm::TablePoint t = arm::pixels_to_base(arm, p, p, p, unused);
    return Eigen::Vector2d(t.x_mm, t.y_mm);
  }
  if (px_per_cm <= 0) return std::nullopt;
  arm::TablePoint t = arm::vision_to_base(arm, p / px_per_cm, 0);
  return Eigen::Vector2d(t.x_mm, t.y_mm);
}

// The camera at the scan pose (the URDF's camera_optical sits at the tool point there) and the four corners of
// its frame on the table. The mount map's corners use the scale at the image centre (px_per_cm of the scan).
json camera_view(const arm::ArmConfig& arm, const json& detections) {
  Eigen::Vector3d apex = arm::fk(arm.links, arm.scan).translation();
  json view{{"apex_mm", {r2(apex.x()), r2(apex.y()), r2(apex.z())}}, {"corners_mm", nullptr}};
  auto size = frame_size(arm, detections);
  double ppc = 0;
  if (detections.is_object() && detections.value("px_per_cm", json()).is_number()) ppc = detections["px_per_cm"];
  if (!size) return view;
  json corners = json::array();
  const int kCorners[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};  // top left, top right, bottom right, bottom left
  for (const auto& c : kCorners) {
    auto p = pixel_on_table(arm, Eigen::Vector2d(c[0] * size->x(), c[1] * size->y()), ppc);
    if (!p) return view;
    corners.push_back({r2(p->x()), r2(p->y()), r2(arm.heights.table_z_mm)});
  }
  view["corners_mm"] = corners;
  return view;
}

// One detected object on the table, as plan_pick_steps would place it; null when the map cannot (uncalibrated
// vision, a frame of another size than the workspace calibration's).
json object_on_table(const arm::ArmConfig& arm, const json& o, const json& detections) {
  const json& grip = o.contains("grip") ? o["grip"] : json::object();
  arm::TablePoint t;
  double opening_mm = 0;
  if (arm.camera.pixel_map) {
    auto size = frame_size(arm, detections);
    if (!size || size->x() != arm.camera.pixel_map->width || size->y() != arm.camera.pixel_map->height ||
        !is_point(o.value("centroid_px", json())) || !is_point(grip.value("p1_px", json())) ||
        !is_point(grip.value("p2_px", json())))
      return nullptr;
    t = arm::pixels_to_base(arm, px(o["centroid_px"]), px(grip["p1_px"]), px(grip["p2_px"]), opening_mm);
  } else {
    if (!is_point(o.value("centroid_cm", json())) || !grip.value("opening_cm", json()).is_number()) return nullptr;
    t = arm::vision_to_base(arm, px(o["centroid_cm"]), grip.value("angle_deg", 0.0));
    opening_mm = grip["opening_cm"].get<double>() * 10;
  }
  // Along the closing line as wide as the opening; across it the length that gives the object's area.
  double opening_px = grip.value("opening_px", 0.0), area_px = o.value("area_px", 0.0);
  double length_mm = opening_px > 0 ? area_px / opening_px * opening_mm / opening_px : opening_mm;
  return {{"index", o.value("index", 0)}, {"label", o.value("label", json())}, {"x_mm", r2(t.x_mm)},
          {"y_mm", r2(t.y_mm)}, {"z_mm", r2(t.z_mm)}, {"yaw_deg", r2(t.yaw_deg)}, {"opening_mm", r2(opening_mm)},
          {"length_mm", r2(length_mm)}, {"feasible", grip.value("feasible", false)}};
}

}  // namespace

json scene_json(const arm::ArmConfig& arm, const json& detections) {
  json places = json::array();
  for (const auto& [name, p] : arm.places)
    places.push_back({{"name", name}, {"x_mm", p.x_mm}, {"y_mm", p.y_mm}, {"z_mm", p.z_mm}, {"yaw_deg", p.yaw_deg}});
  json objects = json::array();
  if (detections.is_object() && detections.contains("objects") && detections["objects"].is_array())
    for (const json& o : detections["objects"])
      if (json t = object_on_table(arm, o, detections); !t.is_null()) objects.push_back(t);
  const arm::GripperConfig& g = arm.gripper;
  return {{"urdf", arm::urdf(arm)},
          {"table_z_mm", arm.heights.table_z_mm},
          {"places", places},
          {"scan_deg", arm.scan},
          {"gripper", {{"closed_us", g.closed_us}, {"open_us", g.open_us}, {"max_opening_mm", g.max_opening_mm}}},
          {"map", arm.camera.pixel_map ? "workspace" : "mount"},
          {"view", camera_view(arm, detections)},
          {"objects", objects}};
}

}  // namespace rbx1::daemon
