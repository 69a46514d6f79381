// main.cpp - rbx1d: reads the config, prepares the arm, serves the control socket until shutdown or a signal.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "console.hpp"
#include "daemon_setup.hpp"
#include "machine.hpp"
#include "mqtt_interface.hpp"
#include "ros2_bridge.hpp"
#include "server.hpp"

namespace {
rbx1::daemon::Server* g_server = nullptr;
void on_signal(int) {
  if (g_server) g_server->stop();  // eventfd write: async-signal-safe
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rbx1d - the RBX1 arm daemon: vision-guided pick-and-place over a Unix control socket"};
  std::string config_file;
  bool check = false;
  rbx1::daemon::Overrides overrides;
  app.add_option("--config", config_file, "the TOML config file (data/rbx1.toml is the bundled default)")->required();
  bool check_syntax = false;
  app.add_flag("--check-config", check,
               "validate the config and open its files and devices as the daemon would; print OK or the errors, "
               "exit 0 or 2");
  app.add_flag("--check-syntax", check_syntax,
               "validate the config's keys and values only, opening nothing (a config for another machine: "
               "packaging); print OK or the errors, exit 0 or 2");
  app.add_option("--port", overrides.port, "serial port, overriding [link] port (also $RBX1_PORT)");
  app.add_option("--socket", overrides.socket, "control socket path, overriding [daemon] socket");
  app.add_option("--annotate", overrides.annotate, "write each scan's annotated image here ([daemon] annotate)");
  app.add_option("--console", overrides.console, "web console HOST:PORT, overriding [console] bind (port 0: any free)");
  app.add_option("--state-dir", overrides.state_dir, "the taught data's folder, overriding [daemon] state_dir");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (overrides.port.empty())
    if (const char* env = std::getenv("RBX1_PORT"); env && *env) overrides.port = env;

  rbx1::daemon::Config config;
  rbx1::config::Errors errors;
  if (!rbx1::daemon::load_config(config_file, overrides, config, errors)) {
    for (const auto& m : errors.messages()) std::fprintf(stderr, "rbx1d: %s: %s\n", config_file.c_str(), m.c_str());
    return 2;
  }
  if (check_syntax && !check) {
    std::printf("OK\n");
    return 0;
  }
  if (check) {
    // Also what start() would open: a file that is missing or unreadable is a config error, found now.
    if (!rbx1::daemon::check_files(config, errors)) {
      for (const auto& m : errors.messages()) std::fprintf(stderr, "rbx1d: %s: %s\n", config_file.c_str(), m.c_str());
      return 2;
    }
    std::printf("OK\n");
    return 0;
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("rbx1d"));  // stdout stays free; journald reads stderr
  spdlog::set_level(spdlog::level::from_str(config.daemon.log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");

  rbx1::daemon::Server server;
  std::string error;
  if (server.open(config.daemon.socket, config.daemon.socket_mode, error) < 0) {
    spdlog::error("control socket: {}", error);
    return 1;
  }
  rbx1::daemon::ServerLimits limits;
  limits.idle_timeout_ms = int(config.daemon.idle_timeout_s * 1000);
  server.set_limits(limits);
  rbx1::daemon::Machine machine(config);
  std::atomic<rbx1::console::Console*> console_ptr{nullptr};
  machine.on_scan([&console_ptr](const cv::Mat& annotated, const nlohmann::json& detections) {
    if (auto* c = console_ptr.load()) c->scan_done(annotated, detections);
  });
  if (machine.start(error) < 0) {
    spdlog::error("{}", error);
    return 1;
  }
  // The web console: a client of the same handler as the socket.
  std::unique_ptr<rbx1::console::Console> console;
  if (config.console.enabled) {
    nlohmann::json places = nlohmann::json::array();
    for (const auto& [name, place] : config.arm.places) places.push_back(name);
    console = std::make_unique<rbx1::console::Console>(
        config.console,
        [&machine](const rbx1::daemon::Request& r, std::shared_ptr<rbx1::daemon::Reply> reply) {
          machine.handle(r, std::move(reply));
        },
        machine.bus(), machine.camera(), config.daemon.job_timeout_s, nlohmann::json{{"places", places}});
    console->serve_scans(config.daemon.state_dir + "/" + rbx1::history::kScansDir);
    if (console->start(error) < 0) {
      spdlog::error("{}", error);
      machine.stop();
      return 1;
    }
    console_ptr = console.get();
    spdlog::info("console: listening on {}{}", console->url(),
                 config.console.token.empty() ? " (no token: loopback only)" : " (token required)");
  }
  // ROS 2 over DDS: one more subscriber of the machine's bus.
  std::unique_ptr<rbx1::ros2::Ros2Bridge> ros2;
  if (config.ros2.enabled) {
    ros2 = std::make_unique<rbx1::ros2::Ros2Bridge>(config.ros2, config.arm);
    if (ros2->start(machine.bus(), error) < 0) {
      spdlog::error("{}", error);
      machine.stop();
      if (console) console->stop();
      return 1;
    }
  }
  // MQTT: a subscriber of the daemon's bus and a client of the same handler as the socket.
  std::unique_ptr<rbx1::mqtt::MqttInterface> mqtt;
  if (config.mqtt.enabled) {
    mqtt = std::make_unique<rbx1::mqtt::MqttInterface>(
        config.mqtt, config.daemon.arm_id, machine.bus(),
        [&machine](const rbx1::daemon::Request& r, std::shared_ptr<rbx1::daemon::Reply> reply) {
          machine.handle(r, std::move(reply));
        },
        config.daemon.state_dir);
    if (mqtt->start(error) < 0) {
      spdlog::error("{}", error);
      if (ros2) ros2->stop();
      machine.stop();
      if (console) console->stop();
      return 1;
    }
    spdlog::info("mqtt: {}:{} as {}, topics under {}/", config.mqtt.host, config.mqtt.port, config.mqtt.client_id,
                 config.mqtt.prefix);
  }
  g_server = &server;
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);
  std::signal(SIGPIPE, SIG_IGN);
  machine.on_shutdown([&server] { server.stop(); });
  spdlog::info("listening on {} (port {})", server.path(), config.link.port);
  server.run([&machine](const rbx1::daemon::Request& r, std::shared_ptr<rbx1::daemon::Reply> reply) {
    machine.handle(r, std::move(reply));
  });
  spdlog::info("shutting down");
  machine.stop();  // ends running jobs, so the console's waiting requests get their replies
  if (ros2) ros2->stop();
  if (mqtt) mqtt->stop();  // after the jobs: their final replies still go out; then "offline"
  console_ptr = nullptr;
  if (console) console->stop();
  g_server = nullptr;
  return 0;
}
