// probes.hpp - what rbx1-avrsim measures on the simulated board: STEP pulses with DIR per joint, interrupt
// durations per vector (the step ISR among them), the e-stop latency, and UART0 exchange times.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "rbx1_messages.h"  // RBX1_JOINTS

extern "C" {
#include "sim_avr.h"
}

namespace rbx1::avrsim {

struct VectorStats {
  uint64_t count = 0, total = 0, max = 0;        // every call
  uint64_t step_calls = 0, step_total = 0, step_max = 0;  // calls that raised at least one STEP pulse
  uint64_t pulses = 0;                           // STEP rising edges raised inside this vector
};

class Probes {
 public:
  // Hooks the STEP/DIR/EN pins of the pin map and every interrupt vector of avr. isr_vector < 0: the step ISR is
  // the vector that raised the most STEP pulses.
  void attach(avr_t* avr, int isr_vector);
  // The board was reset: no interrupt is running any more.
  void on_reset();
  // A measurement window starts: window_first_pulse_cycle is the first pulse after this.
  void start_window() {
    window_any_ = false;
    exchanges_ = 0;
    exchange_total_ = 0;
    in_request_ = false;  // an exchange in flight belongs to the previous window
    rx_bytes_ = tx_bytes_ = 0;
  }
  // The e-stop input was just asserted (at the current cycle).
  void on_estop_edge();
  // The e-stop input was released: later pulses belong to new motion, not to the stop.
  void on_estop_release() { finish_estop_event(); }
  nlohmann::json to_json() const;
  int step_vector() const;

 private:
  static void on_step(avr_irq_t* irq, uint32_t value, void* param);
  static void on_enable(avr_irq_t* irq, uint32_t value, void* param);
  static void on_vector(avr_irq_t* irq, uint32_t value, void* param);
  static void on_uart_in(avr_irq_t* irq, uint32_t value, void* param);
  static void on_uart_out(avr_irq_t* irq, uint32_t value, void* param);
  void close_exchange();
  void step_edge(int joint, uint32_t value);
  void finish_estop_event();

  avr_t* avr_ = nullptr;
  int forced_vector_ = -1;
  std::array<int64_t, RBX1_JOINTS> steps_{};
  std::array<uint64_t, RBX1_JOINTS> pulses_{};
  std::array<uint8_t, RBX1_JOINTS> step_level_{};  // reset level of a port pin: 0
  std::array<uint8_t, RBX1_JOINTS> enable_level_{};

  struct Running {
    uint8_t vector;
    uint64_t entry;
    uint64_t pulses;
  };
  std::vector<Running> running_;           // nested interrupts, innermost last
  std::array<VectorStats, 64> vectors_{};

  // e-stop: cycles from the input edge to the last STEP pulse after it, worst over edges met while moving.
  // UART0 exchanges: first byte of a request into the UART to the last response byte written to UDR0.
  bool in_request_ = false, answered_ = false;
  uint64_t request_start_ = 0, last_out_ = 0;
  uint64_t exchanges_ = 0, exchange_total_ = 0;
  // UART0 bytes since the window began: count, first and last received (into the UART), last written to UDR0.
  uint64_t rx_bytes_ = 0, tx_bytes_ = 0, first_rx_ = 0, last_rx_ = 0, last_tx_ = 0;

  uint64_t first_pulse_cycle_ = 0;
  uint64_t window_first_ = 0;
  bool window_any_ = false;
  uint64_t last_pulse_cycle_ = 0;
  bool any_pulse_ = false;
  bool estop_open_ = false;        // an edge met while moving, still collecting pulses
  uint64_t estop_edge_ = 0;
  uint64_t estop_last_pulse_ = 0;  // 0: none after the edge
  uint64_t estop_disabled_at_ = 0; // cycle when every driver was disabled after the edge, 0: not yet
  std::array<uint64_t, 64> entry_after_edge_{};  // first entry of each vector after the edge, 0: none yet
  int64_t estop_reaction_worst_ = -1;           // edge to the step ISR's first call after it
  int estop_events_ = 0;
  int64_t estop_worst_ = -1;
  int64_t estop_disable_worst_ = -1;
};

}  // namespace rbx1::avrsim
