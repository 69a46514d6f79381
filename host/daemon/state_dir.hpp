// state_dir.hpp - the state directory ([daemon] state_dir): what the operator taught (scan pose, places, workspace
// calibration, background, library), written atomically, read at start-up over the TOML's defaults.
#pragma once
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "arm_config.hpp"
#include "daemon_setup.hpp"

namespace rbx1::daemon {

// Files in the state directory (host/daemon/README.md "State directory").
inline constexpr const char* kPosesFile = "poses.json";           // {"scan": [6 joint angles, deg]}
inline constexpr const char* kPlacesFile = "places.json";         // {"NAME": {"x_mm", "y_mm", "z_mm", "yaw_deg"}}
inline constexpr const char* kWorkspaceFile = "workspace.json";   // host/calib/workspace_fit.hpp
inline constexpr const char* kBackgroundFile = "background.png";  // the empty table at the scan pose (raw frame)
inline constexpr const char* kLibraryFile = "library.json";       // taught objects (host/perception/library.hpp)

class StateDir {
 public:
  explicit StateDir(std::string dir) : dir_(std::move(dir)) {}
  const std::string& dir() const { return dir_; }
  std::string path(const char* file) const { return dir_ + "/" + file; }

  // Applies every file present over config: scan pose, places (added or replaced by name), workspace map,
  // background and library paths. A missing folder or file changes nothing; a corrupt one is an error
  // "PATH: reason" (the daemon refuses to start rather than run on half of what the operator taught).
  bool apply(Config& config, std::string& error) const;

  // Each save creates the folder if needed and writes one file atomically; false + error "PATH: reason".
  bool save_scan_pose(const arm::Joints& scan, std::string& error) const;
  bool save_place(const std::string& name, const arm::Place& place, std::string& error) const;
  bool save_background(const cv::Mat& frame, std::string& error) const;
  bool ensure(std::string& error) const;  // creates the folder (mode 0755) when missing

 private:
  bool read_json(const char* file, nlohmann::json& out, bool& present, std::string& error) const;
  bool write_json(const char* file, const nlohmann::json& j, std::string& error) const;
  std::string dir_;
};

}  // namespace rbx1::daemon
