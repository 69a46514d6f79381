// commands.hpp - each group of rbx1 subcommands registers itself; its callback sets exit_code (2 = bad usage or input).
#pragma once
#include <CLI/CLI.hpp>

namespace rbx1::cli {
// detect, teach, plot (host/cli/cmd_vision.cpp).
void add_vision_commands(CLI::App& app, int& exit_code);
// calibrate (host/cli/cmd_calibrate.cpp).
void add_calibrate_commands(CLI::App& app, int& exit_code);
// status, scan, pick, home, estop, clear-fault, shutdown: the rbx1d client (host/cli/cmd_daemon.cpp).
void add_daemon_commands(CLI::App& app, int& exit_code);
}  // namespace rbx1::cli
