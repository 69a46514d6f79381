// pinmap.hpp - the firmware's pin map (firmware/rbx1/src/pins.h) as tables rbx1-avrsim can walk.
#pragma once

#include <array>
#include <cstdint>

#include "pins.h"  // firmware/rbx1/src/pins.h
#include "rbx1_messages.h"  // RBX1_JOINTS

namespace rbx1::avrsim {

struct PortPin {
  char port;    // AVR port letter, 'A'..'L'
  uint8_t bit;  // 0..7
};

struct JointPins {
  PortPin step, dir, en, limit;
};

#define RBX1_AVRSIM_JOINT(n)                                                                            \
  JointPins {                                                                                           \
    {RBX1_J##n##_STEP_PORT, RBX1_J##n##_STEP_BIT}, {RBX1_J##n##_DIR_PORT, RBX1_J##n##_DIR_BIT},         \
        {RBX1_J##n##_EN_PORT, RBX1_J##n##_EN_BIT}, {RBX1_J##n##_LIMIT_PORT, RBX1_J##n##_LIMIT_BIT}      \
  }
inline constexpr std::array<JointPins, RBX1_JOINTS> kJoints = {RBX1_AVRSIM_JOINT(1), RBX1_AVRSIM_JOINT(2),
                                                               RBX1_AVRSIM_JOINT(3), RBX1_AVRSIM_JOINT(4),
                                                               RBX1_AVRSIM_JOINT(5), RBX1_AVRSIM_JOINT(6)};
#undef RBX1_AVRSIM_JOINT
inline constexpr PortPin kEstop = {RBX1_ESTOP_PORT, RBX1_ESTOP_BIT};

// Electrical levels, as pins.h fixes them.
inline constexpr uint8_t kStepActive = RBX1_STEP_ACTIVE_LEVEL;
inline constexpr uint8_t kDirPositive = RBX1_DIR_POSITIVE_LEVEL;
inline constexpr uint8_t kEnableActive = RBX1_EN_ACTIVE_LEVEL;
inline constexpr uint8_t kLimitActive = RBX1_LIMIT_TRIGGERED_LEVEL;
inline constexpr uint8_t kEstopActive = RBX1_ESTOP_ASSERTED_LEVEL;

// Data-space address of PORTx on the ATmega2560 (PINx, DDRx, PORTx are consecutive).
inline uint16_t port_register(char port) {
  switch (port) {
    case 'A': return 0x22;
    case 'B': return 0x25;
    case 'C': return 0x28;
    case 'D': return 0x2B;
    case 'E': return 0x2E;
    case 'F': return 0x31;
    case 'G': return 0x34;
    case 'H': return 0x102;
    case 'J': return 0x105;
    case 'K': return 0x108;
    case 'L': return 0x10B;
    default: return 0;
  }
}

}  // namespace rbx1::avrsim
