// main.cpp - the rbx1 CLI: perception commands (detect, teach, calibrate) and the daemon's client commands.
#include <CLI/CLI.hpp>

#include <cstdio>

#include "commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"rbx1 - vision-guided pick-and-place for the RBX1 arm"};
  app.require_subcommand(1);
  int exit_code = 0;
  rbx1::cli::add_vision_commands(app, exit_code);
  rbx1::cli::add_calibrate_commands(app, exit_code);
  rbx1::cli::add_daemon_commands(app, exit_code);
  rbx1::cli::add_operator_commands(app, exit_code);
  rbx1::cli::add_description_commands(app, exit_code);
  rbx1::cli::add_jobs_commands(app, exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const CLI::CallForAllHelp&) {
    std::fputs(app.help("", CLI::AppFormatMode::All).c_str(), stdout);
    return 0;
  } catch (const CLI::ParseError& e) {
    // Bad usage: one clear line and exit 2 (shared/DESIGN.md).
    std::fprintf(stderr, "rbx1: %s\n", e.what());
    return 2;
  }
  return exit_code;
}
