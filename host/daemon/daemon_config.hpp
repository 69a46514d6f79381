// daemon_config.hpp - the [daemon] table: control socket, start-up homing, job timeouts, logging.
#pragma once
#include <string>

#include "config.hpp"
#include "control_client.hpp"

namespace rbx1::daemon {

struct DaemonConfig {
  std::string socket = control::kDefaultSocket;  // control socket path
  unsigned socket_mode = 0660;                   // owner and group (the rbx1 group) may connect
  std::string home_on_start = "declare";         // "home": HOME cycle on the switches; "declare": SET_POSITION(home pose)
  std::string log_level = "info";                // debug | info | warn | error
  double move_timeout_s = 20;       // slack beyond a waypoint's planned duration before the job fails
  double job_timeout_s = 300;       // a whole job (scan, pick, home)
  double reconnect_timeout_s = 30;  // how long a vanished link may stay away before the job fails
  int status_poll_ms = 50;          // STATUS polling while waiting for motion (also the heartbeat then)
  double idle_timeout_s = 60;       // a control connection with no request open and nothing sent is closed
  std::string annotate;             // if set, each scan writes the annotated image (Figure 20) here
  std::string start_pick;           // [gpio] start_button runs `pick start_pick --place start_place`; "" = none
  std::string start_place = "tray";
  bool verify_pick = false;         // after a pick, scan again: the object still there is a pick_failed (pick_check.cpp)
  int pick_retries = 1;             // with verify_pick: picks again this often, each from a fresh detection
  std::string state_dir = "/var/lib/rbx1";  // what the operator taught (state_dir.hpp); overrides the file's values
  std::string arm_id;               // the arm's name to the outside (MQTT prefix, ROS 2 namespace); default: host name
};

// The host name with anything but [A-Za-z0-9_-] made '_': arm_id's default.
std::string default_arm_id();

void parse_daemon_config(config::Section daemon, DaemonConfig& out);

}  // namespace rbx1::daemon
