// commands.hpp - each group of rbx1 subcommands registers itself; its callback sets exit_code (2 = bad usage or input).
#pragma once
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::cli {
// detect, teach, plot (host/cli/cmd_vision.cpp).
void add_vision_commands(CLI::App& app, int& exit_code);
// calibrate (host/cli/cmd_calibrate.cpp).
void add_calibrate_commands(CLI::App& app, int& exit_code);
// status, scan, pick, home, estop, clear-fault, shutdown: the rbx1d client (host/cli/cmd_daemon.cpp).
void add_daemon_commands(CLI::App& app, int& exit_code);
// jog, pose, place, background, calibrate-workspace, markers: the operator's commands (host/cli/cmd_operator.cpp).
void add_operator_commands(CLI::App& app, int& exit_code);
// urdf: the robot description (host/cli/cmd_urdf.cpp).
void add_description_commands(CLI::App& app, int& exit_code);
// sort, clear, recipe save, history: the cell's jobs (host/cli/cmd_jobs.cpp).
void add_jobs_commands(CLI::App& app, int& exit_code);

// $RBX1_SOCKET or the default socket path.
std::string default_socket();
// Sends one request to rbx1d and streams its reply (events as lines, or raw JSON with json). The final result goes
// to result_out when given, and is printed unless print_final is false. timeout_s: how long to wait for the final
// line (< 0: the command's default; 0: no limit). Exit code: 0 ok, 1 the job failed, 2 bad usage, no connection or
// no reply in time.
int run_daemon_request(const std::string& socket, bool json, const daemon::Request& request,
                       nlohmann::json* result_out = nullptr, bool print_final = true, double timeout_s = -1);
}  // namespace rbx1::cli
