// state_dir.cpp - the taught data's files: read over the config at start-up, each written atomically when taught.
#include "state_dir.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "atomic_file.hpp"
#include "kinematics.hpp"
#include "workspace_fit.hpp"

namespace rbx1::daemon {

namespace fs = std::filesystem;

namespace {
bool finite_number(const nlohmann::json& v) { return v.is_number() && std::isfinite(v.get<double>()); }
}  // namespace

bool StateDir::ensure(std::string& error) const {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) {
    error = dir_ + ": cannot create the state directory: " + ec.message();
    return false;
  }
  return true;
}

bool StateDir::read_json(const char* file, nlohmann::json& out, bool& present, std::string& error) const {
  std::string p = path(file);
  present = fs::exists(p);
  if (!present) return true;
  std::ifstream f(p);
  if (!f) {
    error = p + ": " + std::strerror(errno);
    return false;
  }
  std::stringstream ss;
  ss << f.rdbuf();
  out = nlohmann::json::parse(ss.str(), nullptr, false);
  if (out.is_discarded() || !out.is_object()) {
    error = p + ": not a JSON object";
    return false;
  }
  return true;
}

bool StateDir::write_json(const char* file, const nlohmann::json& j, std::string& error) const {
  if (!ensure(error)) return false;
  return write_file_atomic(path(file), j.dump(2) + "\n", error);
}

bool StateDir::apply(Config& config, std::string& error) const {
  nlohmann::json j;
  bool present = false;
  if (!read_json(kPosesFile, j, present, error)) return false;
  if (present && j.contains("scan")) {
    const auto& a = j["scan"];
    arm::Joints scan{};
    bool ok = a.is_array() && a.size() == arm::kJoints;
    for (int i = 0; ok && i < arm::kJoints; ++i) {
      ok = finite_number(a[i]);
      if (ok) scan[i] = a[i].get<double>();
    }
    if (!ok) {
      error = path(kPosesFile) + ": \"scan\" must be " + std::to_string(arm::kJoints) + " joint angles in degrees";
      return false;
    }
    std::string why;
    if (!arm::check_limits(config.arm, scan, why)) {
      error = path(kPosesFile) + ": scan pose: " + why;
      return false;
    }
    config.arm.scan = scan;
  }
  if (!read_json(kPlacesFile, j, present, error)) return false;
  if (present)
    for (const auto& [name, v] : j.items()) {
      if (!v.is_object() || !finite_number(v["x_mm"]) || !finite_number(v["y_mm"]) || !finite_number(v["z_mm"]) ||
          !finite_number(v["yaw_deg"])) {
        error = path(kPlacesFile) + ": place \"" + name + "\" needs numbers x_mm, y_mm, z_mm, yaw_deg";
        return false;
      }
      config.arm.places[name] = {v["x_mm"].get<double>(), v["y_mm"].get<double>(), v["z_mm"].get<double>(),
                                 v["yaw_deg"].get<double>()};
    }
  if (fs::exists(path(kWorkspaceFile))) {
    calib::WorkspaceCalibration w;
    if (!calib::load_workspace(path(kWorkspaceFile), w, error)) return false;
    arm::CameraMount::PixelMap m;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) m.h[r * 3 + k] = w.fit.h(r, k);
    m.width = w.image_size.width;
    m.height = w.image_size.height;
    config.arm.camera.pixel_map = m;
    if (w.table_z_mm) config.arm.heights.table_z_mm = *w.table_z_mm;
  }
  if (fs::exists(path(kBackgroundFile))) config.vision.background_path = path(kBackgroundFile);
  if (fs::exists(path(kLibraryFile))) config.vision.library_path = path(kLibraryFile);
  return true;
}

bool StateDir::save_scan_pose(const arm::Joints& scan, std::string& error) const {
  nlohmann::json j;
  bool present = false;
  if (!read_json(kPosesFile, j, present, error)) return false;
  if (!present) j = nlohmann::json::object();
  j["scan"] = scan;
  return write_json(kPosesFile, j, error);
}

bool StateDir::save_place(const std::string& name, const arm::Place& p, std::string& error) const {
  nlohmann::json j;
  bool present = false;
  if (!read_json(kPlacesFile, j, present, error)) return false;
  if (!present) j = nlohmann::json::object();
  j[name] = {{"x_mm", p.x_mm}, {"y_mm", p.y_mm}, {"z_mm", p.z_mm}, {"yaw_deg", p.yaw_deg}};
  return write_json(kPlacesFile, j, error);
}

bool StateDir::save_background(const cv::Mat& frame, std::string& error) const {
  if (!ensure(error)) return false;
  std::vector<uchar> png;
  if (!cv::imencode(".png", frame, png)) {
    error = path(kBackgroundFile) + ": PNG encoding failed";
    return false;
  }
  return write_file_atomic(path(kBackgroundFile), std::string(png.begin(), png.end()), error);
}

}  // namespace rbx1::daemon
