// latency_probe.cpp - bench helper for tools/bench/daemon-latency: runs the daemon's Machine in-process with a
// simulated e-stop line, injects e-stop edges and prints their CLOCK_MONOTONIC times; measures a bare link round
// trip (STATUS) first as the baseline. The bench script timestamps the frames on the wire (tests/e2e/ptyproxy.py).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "control_client.hpp"
#include "daemon_setup.hpp"
#include "machine.hpp"

using namespace rbx1;

int main(int argc, char** argv) {
  CLI::App app{"rbx1d-latency-probe: e-stop edge -> ESTOP frame, and the bare link round trip"};
  std::string config_file, port;
  int count = 30, baseline = 50;
  app.add_option("--config", config_file)->required();
  app.add_option("--port", port)->required();
  app.add_option("--count", count, "e-stop edges");
  app.add_option("--baseline", baseline, "bare STATUS round trips");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_default_logger(spdlog::stderr_color_mt("probe"));  // stdout carries the JSON lines
  spdlog::set_level(spdlog::level::warn);

  daemon::Config config;
  config::Errors errors;
  daemon::Overrides o;
  o.port = port;
  if (!daemon::load_config(config_file, o, config, errors)) {
    std::fprintf(stderr, "%s\n", errors.joined().c_str());
    return 2;
  }
  std::string error;
  {  // Baseline: the bare link, one STATUS request and its response.
    link::Link l;
    if (l.open(config.link, error) < 0) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return 1;
    }
    nlohmann::json rtts = nlohmann::json::array();
    for (int i = 0; i < baseline; ++i) {
      rbx1_status_resp st{};
      int64_t t0 = gpio::monotonic_ns();
      if (l.status(st) < 0) return 1;
      rtts.push_back(gpio::monotonic_ns() - t0);
    }
    std::printf("%s\n", nlohmann::json{{"baseline_rtt_ns", rtts}}.dump().c_str());
  }
  auto source = std::make_unique<gpio::SimEdgeSource>(false);
  gpio::SimEdgeSource* line = source.get();
  daemon::Machine machine(config, std::move(source));
  if (machine.start(error) < 0) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  for (int i = 0; i < 200; ++i) {
    auto st = machine.call(daemon::Command::Status);
    if (st.is_object() && st["result"].value("ready", false)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  for (int i = 0; i < count; ++i) {
    int64_t t = gpio::monotonic_ns();
    line->inject(true, t);  // the e-stop pressed
    std::printf("%s\n", nlohmann::json{{"edge_ns", t}}.dump().c_str());
    std::fflush(stdout);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
    line->inject(false);  // released (after the debounce window)
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    nlohmann::json r;
    for (int k = 0; k < 5; ++k) {  // on a loaded machine the release may not have been seen yet: try again
      r = machine.call(daemon::Command::ClearFault);
      if (r.is_object() && r.contains("result")) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (!r.is_object() || !r.contains("result")) {
      std::fprintf(stderr, "clear_fault failed: %s\n", r.dump().c_str());
      return 1;
    }
  }
  machine.stop();
  return 0;
}
