// hal_sim.cpp - the HAL implemented on the simulated board (host build): exact timer semantics of the AVR
// (the period set inside the step ISR applies from that ISR on), pins that count pulses, inputs from tests.
#include "hal_sim.hpp"

#include <limits>

#include "hal.h"
#include "pins.h"
#include "rbx1_proto.h"
#include "stepper.h"

namespace rbx1::sim {

Board& board() {
  static Board b;
  return b;
}

void power_on() {
  Board& b = board();
  b.now = 0;
  b.step_due = 0;
  b.profile_due = 0;
  b.in_step_isr = false;
  b.dir_level = 0;
  b.step_level = 0;
  b.drivers_on = 0;
  b.servo_us = 0;
  b.net = {};
  b.pulses = {};
  b.step_isr_calls = 0;
  b.rx.clear();
  b.tx.clear();
}

void erase_eeprom() {
  board().eeprom.fill(0xFF);
  board().eeprom_dirty = true;
}

uint64_t next_due() {
  const Board& b = board();
  uint64_t t = std::numeric_limits<uint64_t>::max();
  if (b.step_due && b.step_due < t) t = b.step_due;
  if (b.profile_due && b.profile_due < t) t = b.profile_due;
  return t;
}

void run_until(uint64_t t) {
  Board& b = board();
  for (;;) {
    uint64_t due = next_due();
    if (due > t) break;
    b.now = due;
    // The step interrupt wins a tie, as its vector comes first on the AVR.
    if (b.step_due == due) {
      b.step_due = 0;  // the ISR sets the next period (the firmware always does, or stops the timer)
      b.in_step_isr = true;
      b.step_isr_calls++;
      st_step_isr();
      b.in_step_isr = false;
    } else {
      b.profile_due = due + kTicksPerMs;
      st_profile_isr();
    }
  }
  if (t > b.now) b.now = t;
}

}  // namespace rbx1::sim

using rbx1::sim::board;

void hal_init(void) {
  auto& b = board();
  b.drivers_on = 0;
  b.step_level = 0;
  b.servo_us = 0;
  b.step_due = 0;
  b.profile_due = b.now + rbx1::sim::kTicksPerMs;
}

uint32_t hal_millis(void) { return (uint32_t)(board().now / rbx1::sim::kTicksPerMs); }

int16_t hal_serial_read(void) {
  auto& b = board();
  if (b.rx.empty()) return -1;
  uint8_t c = b.rx.front();
  b.rx.pop_front();
  return c;
}

void hal_serial_write(const uint8_t* data, uint8_t n) { board().tx.insert(board().tx.end(), data, data + n); }

void hal_step_timer_start(uint16_t ticks) { board().step_due = board().now + ticks; }

void hal_step_timer_period(uint16_t ticks) { board().step_due = board().now + ticks; }

void hal_step_timer_stop(void) { board().step_due = 0; }

void hal_step_high(uint8_t mask) {
  auto& b = board();
  for (int i = 0; i < RBX1_JOINTS; i++) {
    if (!(mask & (1u << i))) continue;
    b.pulses[i]++;
    bool high = (b.dir_level >> i) & 1u;
    b.net[i] += (high == (RBX1_DIR_POSITIVE_LEVEL != 0)) ? 1 : -1;
  }
  b.step_level = mask;
  if (mask && b.on_step) b.on_step(mask, b.now);
}

void hal_step_low(void) { board().step_level = 0; }

void hal_dir_write(uint8_t positive_mask) {
  board().dir_level = RBX1_DIR_POSITIVE_LEVEL ? positive_mask : (uint8_t)(~positive_mask & RBX1_ALL_JOINTS_MASK);
}

void hal_drivers_enable(uint8_t on) { board().drivers_on = on; }

void hal_servo_write(uint16_t pulse_us) { board().servo_us = pulse_us; }

uint8_t hal_limit_inputs(void) {
  auto& b = board();
  uint8_t m = b.limits;
  for (int i = 0; i < RBX1_JOINTS; i++) {
    const auto& s = b.switches[i];
    if (s.present && (s.below ? b.net[i] <= s.at : b.net[i] >= s.at)) m |= (uint8_t)(1u << i);
  }
  return m;
}

uint8_t hal_estop_input(void) { return board().estop ? 1 : 0; }

uint8_t hal_eeprom_read(uint16_t addr) { return addr < board().eeprom.size() ? board().eeprom[addr] : 0xFF; }

void hal_eeprom_write(uint16_t addr, uint8_t value) {
  auto& b = board();
  if (addr >= b.eeprom.size() || b.eeprom_broken || b.eeprom[addr] == value) return;
  b.eeprom[addr] = value;
  b.eeprom_dirty = true;
}

void hal_watchdog_kick(void) {}

uint8_t hal_reset_by_watchdog(void) { return board().watchdog_reset ? 1 : 0; }

hal_irq_state hal_irq_save(void) { return 0; }  // interrupts run between main-loop calls on the host

void hal_irq_restore(hal_irq_state) {}

void hal_entry_done(uint8_t kind, uint16_t n, const int32_t target[RBX1_JOINTS], const int32_t start[RBX1_JOINTS],
                    const int32_t end[RBX1_JOINTS], uint16_t duration_ms, uint16_t pulse_us) {
  if (board().on_entry_done) board().on_entry_done(kind, n, target, start, end, duration_ms, pulse_us);
}

uint16_t hal_capabilities(void) { return RBX1_CAP_SIMULATED; }
