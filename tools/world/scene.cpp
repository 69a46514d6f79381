// scene.cpp - reading the scene file (JSON, every error naming its field) and drawing the errors from the seed.
#include "scene.hpp"

#include <numbers>
#include <cmath>
#include <fstream>
#include <random>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace rbx1::world {

namespace {
using nlohmann::json;

struct Bad : std::runtime_error {
  using std::runtime_error::runtime_error;
};

double num(const json& j, const std::string& where, const char* key, double def, double lo, double hi,
           bool required = false) {
  if (!j.contains(key)) {
    if (required) throw Bad(where + "." + key + ": missing");
    return def;
  }
  const json& v = j[key];
  if (!v.is_number()) throw Bad(where + "." + key + ": must be a number");
  double d = v.get<double>();
  if (!std::isfinite(d) || d < lo || d > hi)
    throw Bad(where + "." + key + ": " + std::to_string(d) + " is outside [" + std::to_string(lo) + ", " +
              std::to_string(hi) + "]");
  return d;
}

template <size_t N>
std::array<double, N> arr(const json& j, const std::string& where, const char* key, std::array<double, N> def,
                          double lo, double hi) {
  if (!j.contains(key)) return def;
  const json& v = j[key];
  if (!v.is_array() || v.size() != N) throw Bad(where + "." + key + ": must be an array of " + std::to_string(N));
  std::array<double, N> out{};
  for (size_t i = 0; i < N; ++i) {
    if (!v[i].is_number() || v[i].get<double>() < lo || v[i].get<double>() > hi)
      throw Bad(where + "." + key + "[" + std::to_string(i) + "]: must be a number in [" + std::to_string(lo) +
                ", " + std::to_string(hi) + "]");
    out[i] = v[i].get<double>();
  }
  return out;
}

const json& table(const json& j, const char* key) {
  static const json empty = json::object();
  if (!j.contains(key)) return empty;
  if (!j[key].is_object()) throw Bad(std::string(key) + ": must be an object");
  return j[key];
}

void parse(const json& j, Scene& s) {
  if (!j.is_object() || j.value("format", "") != "rbx1-world") throw Bad("format: must be \"rbx1-world\"");
  if (j.value("version", 0) != 1) throw Bad("version: must be 1");
  if (j.contains("seed")) {
    if (!j["seed"].is_number_unsigned()) throw Bad("seed: must be a non-negative integer");
    s.seed = j["seed"].get<uint64_t>();
  }
  const json& l = table(j, "light");
  Light& li = s.light;
  li.table_grey = int(num(l, "light", "table_grey", li.table_grey, 0, 255));
  li.table_tint = arr<3>(l, "light", "table_tint", li.table_tint, 0.5, 1.5);
  li.gradient = num(l, "light", "gradient", li.gradient, 0, 0.5);
  li.gradient_dir_deg = num(l, "light", "gradient_dir_deg", li.gradient_dir_deg, -360, 360);
  li.vignette = num(l, "light", "vignette", li.vignette, 0, 0.5);
  li.drift = num(l, "light", "drift", li.drift, 0, 0.5);
  li.gain = num(l, "light", "gain", li.gain, kMinGain, kMaxGain);
  li.offset = num(l, "light", "offset", li.offset, -kMaxOffset, kMaxOffset);
  li.shadow_darkness = num(l, "light", "shadow_darkness", li.shadow_darkness, 0, 0.8);
  li.shadow_azimuth_deg = num(l, "light", "shadow_azimuth_deg", li.shadow_azimuth_deg, -360, 360);
  li.shadow_elevation_deg = num(l, "light", "shadow_elevation_deg", li.shadow_elevation_deg, 10, 90);
  li.noise_sigma = num(l, "light", "noise_sigma", li.noise_sigma, 0, 20);
  li.blur_sigma_px = num(l, "light", "blur_sigma_px", li.blur_sigma_px, 0, 5);

  const json& a = table(j, "arm");
  arm::Links& n = s.nominal.links;
  n.base_height_mm = num(a, "arm", "base_height_mm", n.base_height_mm, 50, 1000);
  n.upper_arm_mm = num(a, "arm", "upper_arm_mm", n.upper_arm_mm, 50, 1000);
  n.forearm_mm = num(a, "arm", "forearm_mm", n.forearm_mm, 50, 1000);
  n.tool_mm = num(a, "arm", "tool_mm", n.tool_mm, 10, 500);

  const json& c = table(j, "camera");
  Camera& cam = s.nominal_camera;
  cam.width = int(num(c, "camera", "width", cam.width, 64, 4096));
  cam.height = int(num(c, "camera", "height", cam.height, 64, 4096));
  cam.fx = num(c, "camera", "fx", cam.fx, 10, 1e5);
  cam.fy = num(c, "camera", "fy", cam.fy, 10, 1e5);
  cam.cx = num(c, "camera", "cx", cam.cx, 0, 4096);
  cam.cy = num(c, "camera", "cy", cam.cy, 0, 4096);
  auto d = arr<5>(c, "camera", "dist", {0, 0, 0, 0, 0}, -2, 2);
  cam.dist.assign(d.begin(), d.end());
  cam.mount_xyz_mm = arr<3>(c, "camera", "mount_xyz_mm", cam.mount_xyz_mm, -500, 500);
  cam.mount_rpy_deg = arr<3>(c, "camera", "mount_rpy_deg", cam.mount_rpy_deg, -360, 360);

  const json& g = table(j, "gripper");
  Gripper& gr = s.gripper;
  gr.closed_us = int(num(g, "gripper", "closed_us", gr.closed_us, 500, 2500));
  gr.open_us = int(num(g, "gripper", "open_us", gr.open_us, 500, 2500));
  if (gr.open_us == gr.closed_us) throw Bad("gripper.open_us: must differ from closed_us");
  gr.max_opening_mm = num(g, "gripper", "max_opening_mm", gr.max_opening_mm, 5, 200);
  gr.finger_width_mm = num(g, "gripper", "finger_width_mm", gr.finger_width_mm, 1, 50);
  gr.finger_thickness_mm = num(g, "gripper", "finger_thickness_mm", gr.finger_thickness_mm, 1, 50);
  gr.finger_length_mm = num(g, "gripper", "finger_length_mm", gr.finger_length_mm, 2, 100);

  const json& e = table(j, "errors");
  s.errors.links_mm = num(e, "errors", "links_mm", 0, 0, 20);
  s.errors.mount_mm = num(e, "errors", "mount_mm", 0, 0, 50);
  s.errors.mount_deg = num(e, "errors", "mount_deg", 0, 0, 20);

  if (!j.contains("objects") || !j["objects"].is_array()) throw Bad("objects: missing (an array)");
  for (size_t i = 0; i < j["objects"].size(); ++i) {
    const json& o = j["objects"][i];
    std::string w = "objects[" + std::to_string(i) + "]";
    if (!o.is_object()) throw Bad(w + ": must be an object");
    Object ob;
    ob.id = int(num(o, w, "id", double(i + 1), 0, 1e6));
    if (!o.contains("class") || !o["class"].is_string()) throw Bad(w + ".class: missing (a string)");
    ob.cls = o["class"].get<std::string>();
    if (!o.contains("outline_mm") || !o["outline_mm"].is_array() || o["outline_mm"].size() < 3)
      throw Bad(w + ".outline_mm: missing (at least 3 points)");
    for (size_t k = 0; k < o["outline_mm"].size(); ++k) {
      const json& p = o["outline_mm"][k];
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
        throw Bad(w + ".outline_mm[" + std::to_string(k) + "]: must be [x, y]");
      ob.outline.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
    ob.grip_yaw_deg = num(o, w, "grip_yaw_deg", 0, -360, 360, true);
    ob.grip_width_mm = num(o, w, "grip_width_mm", 0, 0, 500, true);
    ob.height_mm = num(o, w, "height_mm", ob.height_mm, 0.5, 200);
    ob.bgr = arr<3>(o, w, "bgr", ob.bgr, 0, 255);
    ob.x_mm = num(o, w, "x_mm", 0, -2000, 2000, true);
    ob.y_mm = num(o, w, "y_mm", 0, -2000, 2000, true);
    ob.yaw_deg = num(o, w, "yaw_deg", 0, -360, 360);
    ob.z_mm = num(o, w, "z_mm", 0, -100, 500);
    for (const auto& other : s.objects)
      if (other.id == ob.id) throw Bad(w + ".id: " + std::to_string(ob.id) + " is used twice");
    s.objects.push_back(std::move(ob));
  }
  if (j.contains("places")) {
    if (!j["places"].is_array()) throw Bad("places: must be an array");
    for (size_t i = 0; i < j["places"].size(); ++i) {
      const json& p = j["places"][i];
      std::string w = "places[" + std::to_string(i) + "]";
      if (!p.is_object() || !p.contains("name") || !p["name"].is_string()) throw Bad(w + ".name: missing");
      Place pl;
      pl.name = p["name"].get<std::string>();
      pl.x_mm = num(p, w, "x_mm", 0, -2000, 2000, true);
      pl.y_mm = num(p, w, "y_mm", 0, -2000, 2000, true);
      pl.z_mm = num(p, w, "z_mm", 0, -100, 500);
      pl.yaw_deg = num(p, w, "yaw_deg", 0, -360, 360);
      auto size = arr<2>(p, w, "size_mm", {100, 100}, 1, 2000);
      pl.size_x_mm = size[0];
      pl.size_y_mm = size[1];
      pl.bgr = arr<3>(p, w, "bgr", pl.bgr, 0, 255);
      s.places.push_back(pl);
    }
  }
  if (j.contains("markers_on_table")) {
    if (!j["markers_on_table"].is_boolean()) throw Bad("markers_on_table: must be true or false");
    s.markers_on_table = j["markers_on_table"].get<bool>();
  }
  if (j.contains("markers")) {
    if (!j["markers"].is_array()) throw Bad("markers: must be an array");
    for (size_t i = 0; i < j["markers"].size(); ++i) {
      const json& m = j["markers"][i];
      std::string w = "markers[" + std::to_string(i) + "]";
      if (!m.is_object()) throw Bad(w + ": must be an object");
      Marker mk;
      mk.id = int(num(m, w, "id", 0, 0, 49, true));
      mk.x_mm = num(m, w, "x_mm", 0, -2000, 2000, true);
      mk.y_mm = num(m, w, "y_mm", 0, -2000, 2000, true);
      mk.yaw_deg = num(m, w, "yaw_deg", 0, -360, 360);
      mk.size_mm = num(m, w, "size_mm", mk.size_mm, 5, 500);
      s.markers.push_back(mk);
    }
  }
}

void draw_errors(Scene& s) {
  std::mt19937_64 rng(s.seed * 0x9E3779B97F4A7C15ull + 12345);
  auto draw = [&rng](double mag) { return mag * (2.0 * std::generate_canonical<double, 53>(rng) - 1.0); };
  Errors& e = s.errors;
  for (double& v : e.links_drawn) v = draw(e.links_mm);
  for (double& v : e.mount_xyz_drawn) v = draw(e.mount_mm);
  for (double& v : e.mount_rpy_drawn) v = draw(e.mount_deg);
  s.links = s.nominal.links;
  s.links.base_height_mm += e.links_drawn[0];
  s.links.upper_arm_mm += e.links_drawn[1];
  s.links.forearm_mm += e.links_drawn[2];
  s.links.tool_mm += e.links_drawn[3];
  s.camera = s.nominal_camera;
  for (int i = 0; i < 3; ++i) {
    s.camera.mount_xyz_mm[i] += e.mount_xyz_drawn[i];
    s.camera.mount_rpy_deg[i] += e.mount_rpy_drawn[i];
  }
}
}  // namespace

bool load_scene(const std::string& path, Scene& out, std::string& error, std::optional<uint64_t> seed) {
  std::ifstream f(path);
  if (!f) {
    error = path + ": cannot read the scene file";
    return false;
  }
  Scene s;
  try {
    json j = json::parse(f);
    parse(j, s);
  } catch (const json::exception& e) {
    error = path + ": not valid JSON (" + e.what() + ")";
    return false;
  } catch (const Bad& e) {
    error = path + ": " + e.what();
    return false;
  }
  if (seed) s.seed = *seed;
  draw_errors(s);
  out = std::move(s);
  return true;
}

const Place* place_at(const Scene& s, double x, double y) {
  for (const Place& p : s.places) {
    double a = -p.yaw_deg * std::numbers::pi / 180;
    double dx = x - p.x_mm, dy = y - p.y_mm;
    double u = std::cos(a) * dx - std::sin(a) * dy, v = std::sin(a) * dx + std::cos(a) * dy;
    if (std::abs(u) <= p.size_x_mm / 2 && std::abs(v) <= p.size_y_mm / 2) return &p;
  }
  return nullptr;
}

Polygon placed_outline(const Object& o) {
  double a = o.yaw_deg * std::numbers::pi / 180, c = std::cos(a), s = std::sin(a);
  Polygon out;
  out.reserve(o.outline.size());
  for (const auto& p : o.outline) out.emplace_back(o.x_mm + c * p.x() - s * p.y(), o.y_mm + s * p.x() + c * p.y());
  return out;
}

}  // namespace rbx1::world
