// daemon_config.cpp - reads and range-checks the [daemon] table.
#include "daemon_config.hpp"


namespace rbx1::daemon {

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
  out.annotate = s.string("annotate", out.annotate);
  s.reject_unknown();
}

}  // namespace rbx1::daemon
