// cmd_urdf.cpp - rbx1 urdf: prints the robot description (URDF) of the arm an [arm] config describes.
#include <cstdio>

#include "arm_config.hpp"
#include "commands.hpp"
#include "config.hpp"
#include "urdf.hpp"

namespace rbx1::cli {

namespace {
// The [arm] table of file (the built-in defaults when file is empty); errors name the file and the key.
int print_urdf(const std::string& file) {
  arm::ArmConfig arm = arm::default_arm_config();
  if (!file.empty()) {
    config::Errors errors;
    toml::table root = config::load_file(file, errors);
    if (errors.ok()) {
      config::Section top(&root, "", errors);
      arm::parse_arm_config(top.section("arm"), arm);  // the other tables are the daemon's to check
    }
    if (!errors.ok()) {
      for (const auto& m : errors.messages()) std::fprintf(stderr, "rbx1 urdf: %s: %s\n", file.c_str(), m.c_str());
      return 2;
    }
  }
  std::fputs(arm::urdf(arm).c_str(), stdout);
  return 0;
}
}  // namespace

void add_description_commands(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("urdf", "print the arm's URDF (metres, radians) from the [arm] table of a config");
  auto file = std::make_shared<std::string>();
  cmd->add_option("--config", *file, "the TOML config (default: the built-in [arm] defaults)");
  cmd->callback([file, &exit_code] { exit_code = print_urdf(*file); });
}

}  // namespace rbx1::cli
