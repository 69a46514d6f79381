// board_limits.hpp - the host's joint limits ([arm.joints.jN] max_speed_steps_s, accel_steps_s2) against the
// board's (MAX_SPEED, ACCEL read with CONFIG_GET): the host times straight lines at its keys, so keys above the
// board's would plan motion the firmware runs slower or refuses to follow.
#pragma once
#include <string>

#include "arm_config.hpp"
#include "link.hpp"

namespace rbx1::daemon {

// Reads every joint's MAX_SPEED and ACCEL from the board. false + error when a read fails, or naming every key
// above the board's value (the key, its value, the board's, and what to do).
bool check_board_limits(link::Link& link, const arm::ArmConfig& arm, std::string& error);

}  // namespace rbx1::daemon
