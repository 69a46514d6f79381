// board_limits.cpp - the host's joint limit keys checked against the board's MAX_SPEED and ACCEL (CONFIG_GET).
#include "board_limits.hpp"

#include <cstdio>

namespace rbx1::daemon {

bool check_board_limits(link::Link& link, const arm::ArmConfig& arm, std::string& error) {
  std::string over;
  for (int j = 0; j < arm::kJoints; ++j) {
    const struct {
      uint8_t key;
      const char *board, *host;
      int32_t value;
    } limits[] = {{RBX1_KEY_MAX_SPEED, "MAX_SPEED", "max_speed_steps_s", arm.joints[j].max_speed_steps_s},
                  {RBX1_KEY_ACCEL, "ACCEL", "accel_steps_s2", arm.joints[j].accel_steps_s2}};
    for (const auto& l : limits) {
      rbx1_config_get_resp r{};
      if (int e = link.config_get(uint8_t(j), l.key, r); e < 0 || r.status != RBX1_OK) {
        error = link.name() + ": CONFIG_GET " + l.board + " of joint " + std::to_string(j + 1) + " failed: " +
                (e < 0 ? link::error_text(e) : std::string("refused (") + rbx1_status_name(r.status) + ")");
        return false;
      }
      if (l.value > r.value) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "%sarm.joints.j%d.%s = %ld is above the board's %s %ld", over.empty() ? "" : "; ",
                      j + 1, l.host, long(l.value), l.board, long(r.value));
        over += buf;
      }
    }
  }
  if (over.empty()) return true;
  error = "the config's joint limits exceed the board's: " + over +
          " (lower the keys, or raise the board's with CONFIG_SET: PROTOCOL.md)";
  return false;
}

}  // namespace rbx1::daemon
