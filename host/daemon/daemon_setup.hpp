// daemon_setup.hpp - the whole config file: each part reads its own table; unknown tables are errors.
#pragma once
#include <string>

#include "arm_config.hpp"
#include "config.hpp"
#include "console_config.hpp"
#include "daemon_config.hpp"
#include "frame_source.hpp"
#include "gpio.hpp"
#include "history.hpp"
#include "link.hpp"
#include "mqtt_config.hpp"
#include "operator_config.hpp"
#include "ros2_config.hpp"
#include "vision.hpp"

namespace rbx1::daemon {

struct Config {
  camera::CameraConfig camera;
  vision::VisionOptions vision;
  arm::ArmConfig arm;
  link::LinkConfig link;
  gpio::GpioConfig gpio;
  DaemonConfig daemon;
  console::ConsoleConfig console;
  OperatorConfig op;  // [operator]
  ros2::Ros2Config ros2;
  mqtt::MqttConfig mqtt;
  rbx1::history::HistoryConfig history;  // [history]
};

// Command-line and environment overrides, applied after the file (documented in README.md).
struct Overrides {
  std::string port;      // --port or $RBX1_PORT: [link] port
  std::string socket;    // --socket: [daemon] socket
  std::string annotate;  // --annotate: [daemon] annotate
  std::string console;   // --console: [console] bind
  std::string state_dir; // --state-dir: [daemon] state_dir
};

// Reads and validates file; relative paths in it ([camera] device, [vision] files) are taken relative to the
// file's folder (also [daemon] state_dir). Every problem goes to errors, naming its key. Returns errors.ok().
bool load_config(const std::string& file, const Overrides& overrides, Config& out, config::Errors& errors);

// What Machine::start() would meet (rbx1d --check-config): the vision files (library, background,
// calibration) load, an image or folder camera exists and reads, a /dev camera exists. Problems go to errors,
// naming the key. Returns errors.ok().
bool check_files(const Config& config, config::Errors& errors);

}  // namespace rbx1::daemon
