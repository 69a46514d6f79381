// hal_sim.hpp - the simulated board behind the HAL on the host: a 2 MHz simulated clock with the step timer and
// the 1 kHz profile tick, pins that count pulses, switch and e-stop inputs, in-memory EEPROM, serial queues.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <vector>

#include "rbx1_messages.h"

namespace rbx1::sim {

constexpr uint64_t kTicksPerSecond = 2000000;  // the step timer's clock (F_CPU / 8 on the AVR)
constexpr uint64_t kTicksPerMs = kTicksPerSecond / 1000;

// A switch that closes when the joint's pulse-counted position passes a point (homing tests).
struct SwitchModel {
  bool present = false;
  int64_t at = 0;      // triggered when position <= at (below) or >= at (!below)
  bool below = true;
};

struct Board {
  uint64_t now = 0;  // simulated ticks since power-up
  // Timers: next due time, or 0 when stopped.
  uint64_t step_due = 0;
  uint64_t profile_due = 0;
  bool in_step_isr = false;
  // Outputs.
  uint8_t dir_level = 0;
  uint8_t step_level = 0;
  uint8_t drivers_on = 0;
  uint16_t servo_us = 0;
  std::array<int64_t, RBX1_JOINTS> net{};      // signed pulse count per joint (DIR high = +1)
  std::array<uint64_t, RBX1_JOINTS> pulses{};  // total pulses per joint
  uint64_t step_isr_calls = 0;
  // Inputs.
  uint8_t limits = 0;  // forced switch states (control FIFO `limit J 1`)
  bool estop = false;
  std::array<SwitchModel, RBX1_JOINTS> switches{};
  // Non-volatile memory and reset cause.
  std::array<uint8_t, 4096> eeprom{};
  bool eeprom_dirty = false;
  bool eeprom_broken = false;  // writes are lost (EEPROM_ERROR tests)
  bool watchdog_reset = false;
  // Serial: bytes waiting for the firmware, bytes it sent.
  std::deque<uint8_t> rx;
  std::vector<uint8_t> tx;
  // Observers (tests, move log).
  std::function<void(uint8_t mask, uint64_t t)> on_step;
  std::function<void(uint8_t kind, uint16_t n, const int32_t* target, const int32_t* start, const int32_t* end,
                     uint16_t duration_ms, uint16_t pulse_us)>
      on_entry_done;
};

// The one simulated board (the HAL functions are free functions, like on the AVR).
Board& board();
// Power-on: clock, timers, pins and serial reset; EEPROM, inputs and observers kept. Erase EEPROM to blank.
void power_on();
void erase_eeprom();
// Runs every interrupt due up to simulated time t (in order of due time), advancing the clock to t.
void run_until(uint64_t t);
// Ticks until the next due interrupt, or UINT64_MAX.
uint64_t next_due();

}  // namespace rbx1::sim
