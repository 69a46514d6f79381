// daemon_config.cpp - reads and range-checks the [daemon] table.
#include "daemon_config.hpp"

#include <cctype>
#include <cstring>

#include <unistd.h>

namespace rbx1::daemon {

namespace {
// Like a request's name or place: at most 64 printable characters (it ends up in events and logs).
bool printable(const std::string& s) {
  if (s.size() > 64) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}

// An arm_id is one topic level and one ROS 2 name part: letters, digits, '_' and '-'.
bool valid_arm_id(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (!(isalnum(c) || c == '_' || c == '-')) return false;
  return true;
}
}  // namespace

std::string default_arm_id() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0 || !host[0]) return "rbx1";
  std::string id(host, strnlen(host, 64));
  for (char& c : id)
    if (!(isalnum((unsigned char)c) || c == '_' || c == '-')) c = '_';
  return id;
}

void parse_daemon_config(config::Section s, DaemonConfig& out) {
  out.socket = s.string("socket", out.socket);
  if (out.socket.empty() || out.socket.size() > 100) s.errors().add(s.path() + ".socket", "must be a path of 1..100 characters");
  out.socket_mode = unsigned(s.integer("socket_mode", out.socket_mode, 0, 0777));
  out.home_on_start = s.string("home_on_start", out.home_on_start);
  if (out.home_on_start != "home" && out.home_on_start != "declare")
    s.errors().add(s.path() + ".home_on_start", "must be \"home\" or \"declare\", got \"" + out.home_on_start + "\"");
  out.log_level = s.string("log_level", out.log_level);
  if (out.log_level != "debug" && out.log_level != "info" && out.log_level != "warn" && out.log_level != "error")
    s.errors().add(s.path() + ".log_level", "must be one of debug, info, warn, error");
  out.move_timeout_s = s.number("move_timeout_s", out.move_timeout_s, 0.1, 3600);
  out.job_timeout_s = s.number("job_timeout_s", out.job_timeout_s, 1, 86400);
  out.reconnect_timeout_s = s.number("reconnect_timeout_s", out.reconnect_timeout_s, 0.1, 3600);
  out.status_poll_ms = int(s.integer("status_poll_ms", out.status_poll_ms, 5, 500));
  out.idle_timeout_s = s.number("idle_timeout_s", out.idle_timeout_s, 0.1, 86400);
  out.annotate = s.string("annotate", out.annotate);
  out.start_pick = s.string("start_pick", out.start_pick);
  if (!printable(out.start_pick))
    s.errors().add(s.path() + ".start_pick", "must be an object name of at most 64 printable characters (\"\" = none)");
  out.start_place = s.string("start_place", out.start_place);
  if (out.start_place.empty() || !printable(out.start_place))
    s.errors().add(s.path() + ".start_place", "must be a place name of 1..64 printable characters");
  out.verify_pick = s.boolean("verify_pick", out.verify_pick);
  out.pick_retries = int(s.integer("pick_retries", out.pick_retries, 0, 3));
  out.state_dir = s.string("state_dir", out.state_dir);
  if (out.state_dir.empty()) s.errors().add(s.path() + ".state_dir", "must be a folder path");
  out.arm_id = s.string("arm_id", out.arm_id.empty() ? default_arm_id() : out.arm_id);
  if (!valid_arm_id(out.arm_id))
    s.errors().add(s.path() + ".arm_id", "must be 1..64 letters, digits, '_' or '-' (it names the arm's MQTT topics), got \"" +
                                             out.arm_id + "\"");
  s.reject_unknown();
}

}  // namespace rbx1::daemon
