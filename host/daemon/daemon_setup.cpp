// daemon_setup.cpp - strings the parts' config readers together over one TOML file.
#include "daemon_setup.hpp"

#include <filesystem>

namespace rbx1::daemon {

namespace fs = std::filesystem;

namespace {
void resolve(std::string& path, const fs::path& dir) {
  if (path.empty() || fs::path(path).is_absolute()) return;
  path = (dir / path).lexically_normal().string();
}
}  // namespace

bool load_config(const std::string& file, const Overrides& overrides, Config& out, config::Errors& errors) {
  toml::table root = config::load_file(file, errors);
  if (!errors.ok()) return false;
  config::Section top(&root, "", errors);
  out.arm = arm::default_arm_config();
  camera::parse_camera_config(top.section("camera"), out.camera);
  vision::parse_vision_config(top.section("vision"), out.vision);
  arm::parse_arm_config(top.section("arm"), out.arm);
  link::parse_link_config(top.section("link"), out.link);
  gpio::parse_gpio_config(top.section("gpio"), out.gpio);
  parse_daemon_config(top.section("daemon"), out.daemon);
  console::parse_console_config(top.section("console"), out.console);
  parse_operator_config(top.section("operator"), out.op);
  ros2::parse_ros2_config(top.section("ros2"), out.daemon.arm_id, out.ros2);  // the ROS namespace names the arm
  mqtt::parse_mqtt_config(top.section("mqtt"), out.daemon.arm_id, out.mqtt);
  rbx1::history::parse_history_config(top.section("history"), out.history);
  top.reject_unknown();  // a misspelt table name must not pass silently

  if (!overrides.port.empty()) out.link.port = overrides.port;
  if (!overrides.socket.empty()) out.daemon.socket = overrides.socket;
  if (!overrides.annotate.empty()) out.daemon.annotate = overrides.annotate;
  if (!overrides.console.empty()) console::override_console_bind(overrides.console, out.console, errors);
  if (out.link.port.empty()) errors.add("link.port", "must be set (in the file, with --port, or $RBX1_PORT)");
  // The start button runs a configured pick: a button that would do nothing, or a pick to a place the arm does
  // not know, is a mistake in the file, not something to discover when the button is pressed.
  if (out.gpio.start_button.configured() && out.daemon.start_pick.empty())
    errors.add("daemon.start_pick", "must name the object to pick when [gpio] start_button is configured");
  if (!out.daemon.start_pick.empty() && !out.arm.places.count(out.daemon.start_place)) {
    std::string known;
    for (const auto& [k, v] : out.arm.places) known += (known.empty() ? "" : ", ") + k;
    errors.add("daemon.start_place", "no place \"" + out.daemon.start_place + "\" in [arm] places (known: " + known + ")");
  }
  if (out.camera.device.empty()) errors.add("camera.device", "must be set (a /dev/videoN, an image, a folder or unix:SOCKET)");
  // px_per_cm = 0 leaves the daemon without table coordinates: every pick would fail "uncalibrated".
  if (auto vis = top.section("vision"); vis.has("px_per_cm") && !(out.vision.px_per_cm > 0))
    errors.add("vision.px_per_cm", "must be above 0 (or leave it out and set vision.calibration)");

  fs::path dir = fs::absolute(fs::path(file)).parent_path();
  // Devices and frame servers (unix:PATH) are absolute; images and folders are relative to the config file.
  if (out.camera.device.rfind("/dev/", 0) != 0 && out.camera.device.rfind("unix:", 0) != 0)
    resolve(out.camera.device, dir);
  resolve(out.vision.background_path, dir);
  resolve(out.vision.library_path, dir);
  resolve(out.vision.calibration_path, dir);
  resolve(out.daemon.state_dir, dir);
  for (std::string* p : {&out.mqtt.password_file, &out.mqtt.ca_file, &out.mqtt.cert_file, &out.mqtt.key_file}) resolve(*p, dir);
  if (!overrides.state_dir.empty()) out.daemon.state_dir = fs::absolute(overrides.state_dir).lexically_normal().string();
  return errors.ok();
}

bool check_files(const Config& config, config::Errors& errors) {
  std::string error;
  const auto& v = config.vision;
  for (const auto& [key, path] : {std::pair<const char*, const std::string&>{"vision.library", v.library_path},
                                  {"vision.background", v.background_path},
                                  {"vision.calibration", v.calibration_path}})
    if (!path.empty() && !fs::exists(path)) errors.add(key, path + ": no such file");
  if (errors.ok() && !vision::Vision::create(v, error)) errors.add("vision", error);
  const auto& m = config.mqtt;
  if (m.enabled) {
    for (const auto& [key, path] : {std::pair<const char*, const std::string&>{"mqtt.ca_file", m.ca_file},
                                    {"mqtt.cert_file", m.cert_file}, {"mqtt.key_file", m.key_file}})
      if (!path.empty() && !fs::exists(path)) errors.add(key, path + ": no such file");
    std::string password;
    if (!mqtt::read_password(m, password, error)) errors.add("mqtt.password_file", error.substr(error.find(' ') + 1));
  }
  const std::string& dev = config.camera.device;
  if (dev.rfind("/dev/", 0) == 0) {
    if (!fs::exists(dev)) errors.add("camera.device", dev + ": no such device");
  } else if (!dev.empty()) {
    if (!fs::exists(dev)) errors.add("camera.device", dev + ": no such file or folder");
    else if (!camera::open_source(config.camera, error)) errors.add("camera.device", error);
  }
  return errors.ok();
}

}  // namespace rbx1::daemon
