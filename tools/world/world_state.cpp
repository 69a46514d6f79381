// world_state.cpp - the gripper model and the arm's sweep: grasps, collisions, releases, each logged as an event.
#include "world_state.hpp"

#include <numbers>
#include <algorithm>
#include <cmath>

#include "joint_steps.hpp"
#include "kinematics.hpp"

namespace rbx1::world {

using nlohmann::json;

namespace {
constexpr double kSampleDeg = 0.5;  // a move is checked every half degree of its largest joint change
constexpr int kTable = -1;          // the table in a move's list of things hit
constexpr double kClosedMm = 1.0;   // closing below this with nothing held: the fingers closed on nothing

double r2(double v) { return std::round(v * 100) / 100; }

double axis_diff_deg(double a, double b) {
  double d = std::fmod(std::abs(a - b), 180.0);
  return std::min(d, 180.0 - d);
}

Eigen::Isometry3d object_frame(const Object& o) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(o.x_mm, o.y_mm, o.z_mm);
  t.linear() = Eigen::AngleAxisd(o.yaw_deg * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return t;
}

bool segments_cross(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2, const Eigen::Vector2d& q1,
                    const Eigen::Vector2d& q2) {
  auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
  double d1 = cross(p2 - p1, q1 - p1), d2 = cross(p2 - p1, q2 - p1);
  double d3 = cross(q2 - q1, p1 - q1), d4 = cross(q2 - q1, p2 - q1);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

Polygon pad(const Eigen::Vector2d& c, const Eigen::Vector2d& u, double from, double to, double half_width) {
  Eigen::Vector2d v(-u.y(), u.x());
  return {c + u * from - v * half_width, c + u * to - v * half_width, c + u * to + v * half_width,
          c + u * from + v * half_width};
}
}  // namespace

bool point_in_polygon(const Eigen::Vector2d& p, const Polygon& poly) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto& a = poly[i];
    const auto& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

bool polygons_overlap(const Polygon& a, const Polygon& b) {
  for (const auto& p : a)
    if (point_in_polygon(p, b)) return true;
  for (const auto& p : b)
    if (point_in_polygon(p, a)) return true;
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t k = 0; k < b.size(); ++k)
      if (segments_cross(a[i], a[(i + 1) % a.size()], b[k], b[(k + 1) % b.size()])) return true;
  return false;
}

bool extent_in_band(const Polygon& poly, const Eigen::Vector2d& c, const Eigen::Vector2d& u, double half_width,
                    double& lo, double& hi) {
  // Clip the polygon (in (s, t) = (along u, across) coordinates) to |t| <= half_width, keep the s range.
  Eigen::Vector2d v(-u.y(), u.x());
  std::vector<Eigen::Vector2d> st;
  for (const auto& p : poly) st.emplace_back((p - c).dot(u), (p - c).dot(v));
  auto clip = [](const std::vector<Eigen::Vector2d>& in, double sign, double limit) {
    std::vector<Eigen::Vector2d> out;
    for (size_t i = 0; i < in.size(); ++i) {
      const auto& a = in[i];
      const auto& b = in[(i + 1) % in.size()];
      bool ain = sign * a.y() <= limit, bin = sign * b.y() <= limit;
      if (ain) out.push_back(a);
      if (ain != bin) {
        double t = (limit - sign * a.y()) / (sign * (b.y() - a.y()));
        out.push_back(a + (b - a) * t);
      }
    }
    return out;
  };
  auto clipped = clip(clip(st, 1.0, half_width), -1.0, half_width);
  if (clipped.empty()) return false;
  lo = 1e18;
  hi = -1e18;
  for (const auto& p : clipped) {
    lo = std::min(lo, p.x());
    hi = std::max(hi, p.x());
  }
  return hi > lo;
}

World::World(Scene scene) : scene_(std::move(scene)), initial_(scene_.objects) {
  joints_ = scene_.nominal.home;
  opening_mm_ = 0;
}

bool World::table_free(std::string& error) const {
  if (held_.index < 0) return true;
  error = "the gripper holds object " + std::to_string(scene_.objects[size_t(held_.index)].id) +
          ": release it before changing the table";
  return false;
}

bool World::set_markers_on_table(bool on, std::string& error) {
  if (!table_free(error)) return false;
  if (on != scene_.markers_on_table) emit({{"event", "table"}, {"markers_on_table", on}});
  scene_.markers_on_table = on;
  return true;
}

bool World::set_table_cleared(bool cleared, std::string& error) {
  if (!table_free(error)) return false;
  if (cleared != scene_.table_cleared) emit({{"event", "table"}, {"cleared", cleared}});
  scene_.table_cleared = cleared;
  return true;
}

bool World::set_light(double gain, double offset, std::string& error) {
  if (!(gain >= kMinGain && gain <= kMaxGain) || !(offset >= -kMaxOffset && offset <= kMaxOffset)) {
    error = "light: gain within " + std::to_string(kMinGain) + ".." + std::to_string(kMaxGain) +
            ", offset within +-" + std::to_string(kMaxOffset);
    return false;
  }
  scene_.light.gain = gain;
  scene_.light.offset = offset;
  emit({{"event", "light"}, {"gain", gain}, {"offset", offset}});
  return true;
}

Eigen::Isometry3d World::tool(const arm::Joints& deg) const { return arm::fk(scene_.links, deg); }

void World::emit(json ev) {
  ev["entry"] = entries_;
  events_.push_back(ev);
  if (on_event_) on_event_(ev);
}

bool World::apply_log_line(const std::string& line, std::string& error) {
  json j;
  try {
    j = json::parse(line);
  } catch (const json::exception& e) {
    error = "move log: not JSON: " + line;
    return false;
  }
  auto steps = [&j](const char* key, arm::Steps& out) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 6) return false;
    for (int i = 0; i < 6; ++i) out[i] = j[key][i].get<int32_t>();
    return true;
  };
  arm::Steps start{}, end{};
  if (!j.contains("kind") || !steps("start", start) || !steps("end", end)) {
    error = "move log: not a queue entry: " + line;
    return false;
  }
  ++entries_;
  sim_ms_ += j.value("duration_ms", 0);
  arm::Joints a = arm::steps_to_joints(scene_.nominal, start), b = arm::steps_to_joints(scene_.nominal, end);
  if (j["kind"] == "gripper") {
    joints_ = b;
    const Gripper& g = scene_.gripper;
    double f = (j.value("pulse_us", 0) - g.closed_us) / double(g.open_us - g.closed_us);
    gripper_to(std::clamp(f, 0.0, 1.0) * g.max_opening_mm);
    return true;
  }
  double largest = 0;
  for (int i = 0; i < 6; ++i) largest = std::max(largest, std::abs(b[i] - a[i]));
  int n = std::clamp(int(std::ceil(largest / kSampleDeg)), 1, 2000);
  std::vector<int> hit;
  for (int k = 1; k <= n; ++k) {
    arm::Joints q;
    for (int i = 0; i < 6; ++i) q[i] = a[i] + (b[i] - a[i]) * k / n;  // the firmware's moves are coordinated
    at_pose(q, k == n, hit);
  }
  joints_ = b;
  return true;
}

void World::at_pose(const arm::Joints& deg, bool, std::vector<int>& hit) {
  Eigen::Isometry3d t = tool(deg);
  if (held_.index >= 0) {
    Object& o = scene_.objects[size_t(held_.index)];
    Eigen::Isometry3d f = t * held_.in_tool;
    o.x_mm = f.translation().x();
    o.y_mm = f.translation().y();
    o.z_mm = f.translation().z();
    Eigen::Vector3d x = f.linear().col(0);
    o.yaw_deg = std::atan2(x.y(), x.x()) * 180 / std::numbers::pi;
  }
  const Gripper& g = scene_.gripper;
  Eigen::Vector3d ux = t.linear().col(0);
  if (std::hypot(ux.x(), ux.y()) < 1e-6) return;  // closing line vertical: the fingers point sideways
  Eigen::Vector2d c = t.translation().head<2>(), u = ux.head<2>().normalized();
  double tip = t.translation().z();
  Polygon pads[2] = {pad(c, u, opening_mm_ / 2, opening_mm_ / 2 + g.finger_thickness_mm, g.finger_width_mm / 2),
                     pad(c, -u, opening_mm_ / 2, opening_mm_ / 2 + g.finger_thickness_mm, g.finger_width_mm / 2)};
  if (tip < 0 && !std::count(hit.begin(), hit.end(), kTable)) {
    hit.push_back(kTable);
    ++collisions_;
    emit({{"event", "collision"}, {"object", nullptr}, {"class", "table"},
          {"tool_mm", {r2(t.translation().x()), r2(t.translation().y()), r2(tip)}}});
  }
  for (size_t k = 0; k < scene_.objects.size() && objects_on_table(scene_); ++k) {
    const Object& o = scene_.objects[k];
    if (int(k) == held_.index || std::count(hit.begin(), hit.end(), int(k))) continue;
    if (tip >= o.z_mm + o.height_mm || tip + g.finger_length_mm <= o.z_mm) continue;
    Polygon out = placed_outline(o);
    for (int f = 0; f < 2; ++f) {
      if (!polygons_overlap(pads[f], out)) continue;
      hit.push_back(int(k));
      ++collisions_;
      emit({{"event", "collision"}, {"object", o.id}, {"class", o.cls}, {"finger", f},
            {"tool_mm", {r2(t.translation().x()), r2(t.translation().y()), r2(tip)}},
            {"object_top_mm", r2(o.z_mm + o.height_mm)}});
      break;
    }
  }
}

void World::gripper_to(double opening) {
  const double before = opening_mm_;
  Eigen::Isometry3d t = tool(joints_);
  Eigen::Vector3d ux = t.linear().col(0);
  Eigen::Vector2d c = t.translation().head<2>(), u = ux.head<2>().normalized();
  double tip = t.translation().z();
  const Gripper& g = scene_.gripper;
  if (opening < before - 0.5 && held_.index < 0) {
    // Closing: the first object between the fingers, within their height, is grasped when both fingers are
    // outside it (they straddle it) and it is at least as wide as where the fingers stop.
    std::string why = "nothing between the fingers";
    for (size_t k = 0; k < scene_.objects.size() && objects_on_table(scene_); ++k) {
      Object& o = scene_.objects[k];
      if (tip >= o.z_mm + o.height_mm || tip + g.finger_length_mm <= o.z_mm) continue;
      double lo, hi;
      if (!extent_in_band(placed_outline(o), c, u, g.finger_width_mm / 2, lo, hi)) continue;
      if (hi <= -before / 2 || lo >= before / 2) continue;  // beside the fingers, not between them
      if (lo < -before / 2 || hi > before / 2) {
        why = "a finger is on object " + std::to_string(o.id);
        continue;
      }
      if (hi - lo < opening) continue;  // narrower than where the fingers stop: they do not touch it
      // The fingers centre the object on the closing line, then hold it.
      double shift = -(lo + hi) / 2;
      double offset = std::hypot(o.x_mm - c.x(), o.y_mm - c.y());
      double closing_yaw = std::atan2(u.y(), u.x()) * 180 / std::numbers::pi;
      double yaw_err = axis_diff_deg(closing_yaw, o.yaw_deg + o.grip_yaw_deg);
      o.x_mm += u.x() * shift;
      o.y_mm += u.y() * shift;
      held_.index = int(k);
      held_.in_tool = t.inverse() * object_frame(o);
      opening_mm_ = hi - lo;
      ++grasps_;
      emit({{"event", "grasp"}, {"object", o.id}, {"class", o.cls}, {"offset_mm", r2(offset)},
            {"yaw_error_deg", r2(yaw_err)}, {"width_mm", r2(hi - lo)}, {"true_grip_width_mm", r2(o.grip_width_mm)},
            {"tool_mm", {r2(c.x()), r2(c.y()), r2(tip)}}});
      return;
    }
    opening_mm_ = opening;
    if (opening > kClosedMm) return;  // narrowed in the air (opened for a smaller object): not a grasp
    ++closed_empty_;
    emit({{"event", "closed_empty"}, {"reason", why}, {"tool_mm", {r2(c.x()), r2(c.y()), r2(tip)}}});
    return;
  }
  if (opening > before + 0.5 && held_.index >= 0) {
    // Release: the object drops straight down onto what is under it (a place's floor or the table).
    Object& o = scene_.objects[size_t(held_.index)];
    held_.index = -1;
    const Place* p = place_at(scene_, o.x_mm, o.y_mm);
    o.z_mm = p ? p->z_mm : 0.0;
    ++placements_;
    json ev{{"event", "placement"}, {"object", o.id}, {"class", o.cls}, {"place", p ? json(p->name) : json(nullptr)},
            {"x_mm", r2(o.x_mm)}, {"y_mm", r2(o.y_mm)}, {"yaw_deg", r2(o.yaw_deg)}};
    if (p) ev["error_mm"] = r2(std::hypot(o.x_mm - p->x_mm, o.y_mm - p->y_mm));
    emit(ev);
  }
  opening_mm_ = opening;
}

json World::state() const {
  json s;
  s["seed"] = scene_.seed;
  s["entries"] = entries_;
  s["motion_ms"] = sim_ms_;
  const Errors& e = scene_.errors;
  s["errors"] = {{"links_mm", e.links_drawn}, {"mount_xyz_mm", e.mount_xyz_drawn},
                 {"mount_rpy_deg", e.mount_rpy_drawn},
                 {"magnitudes", {{"links_mm", e.links_mm}, {"mount_mm", e.mount_mm}, {"mount_deg", e.mount_deg}}}};
  Eigen::Isometry3d t = tool(joints_);
  json jd = json::array();
  for (double d : joints_) jd.push_back(r2(d));
  s["arm"] = {{"joints_deg", jd},
              {"tool_mm", {r2(t.translation().x()), r2(t.translation().y()), r2(t.translation().z())}},
              {"opening_mm", r2(opening_mm_)},
              {"holding", held_.index >= 0 ? json(scene_.objects[size_t(held_.index)].id) : json(nullptr)}};
  json objs = json::array();
  for (size_t k = 0; k < scene_.objects.size(); ++k) {
    const Object& o = scene_.objects[k];
    const Place* p = int(k) == held_.index ? nullptr : place_at(scene_, o.x_mm, o.y_mm);
    objs.push_back({{"id", o.id}, {"class", o.cls}, {"x_mm", r2(o.x_mm)}, {"y_mm", r2(o.y_mm)}, {"z_mm", r2(o.z_mm)},
                    {"yaw_deg", r2(o.yaw_deg)}, {"held", int(k) == held_.index},
                    {"place", p ? json(p->name) : json(nullptr)},
                    {"moved_mm", r2(std::hypot(o.x_mm - initial_[k].x_mm, o.y_mm - initial_[k].y_mm))}});
  }
  s["objects"] = objs;
  s["markers_on_table"] = scene_.markers_on_table;
  s["table_cleared"] = scene_.table_cleared;
  s["light"] = {{"gain", scene_.light.gain}, {"offset", scene_.light.offset}};
  json marks = json::array();
  for (const Marker& m : scene_.markers)
    marks.push_back({{"id", m.id}, {"x_mm", m.x_mm}, {"y_mm", m.y_mm}, {"size_mm", m.size_mm}});
  s["markers"] = marks;
  s["counts"] = {{"grasps", grasps_}, {"closed_empty", closed_empty_}, {"collisions", collisions_},
                 {"placements", placements_}};
  s["events"] = events_;
  return s;
}

}  // namespace rbx1::world
