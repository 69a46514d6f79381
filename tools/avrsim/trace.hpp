// trace.hpp - rbx1-avrsim's pin-level timing logger: every STEP/DIR edge per joint, every interrupt entry, exit
// and raise, every change of the SREG I bit, every OCR1A write with the Timer1 count at that instant, and the
// e-stop input edges, each stamped with the simulated cycle, written as text lines to a file (tools/avrsim/timing.py
// analyses it). Interrupts-off windows (I bit 1 -> 0 -> 1) of kShortWindow cycles or more are logged one a line
// with where they began; shorter ones (the main loop's many brief guards) are only counted, in the closing line.
// Optionally the calls of one function (its first instruction's address): entry to return, and the same less the
// interrupts that ran inside it.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

#include "rbx1_messages.h"  // RBX1_JOINTS

extern "C" {
#include "sim_avr.h"
}

namespace rbx1::avrsim {

class Trace {
 public:
  // Opens FILE and hooks the pins, vectors and Timer1 registers of avr. Returns false with error set.
  bool open(avr_t* avr, const std::string& path, std::string& error);
  // Times the calls of the main-loop function whose first instruction is at byte address pc (0: none).
  void time_function(uint32_t pc) { fn_pc_ = pc; }
  // After every instruction: logs a change of the I bit (cli, sei, interrupt entry, RETI, writes to SREG), and
  // the timed function's entry and return.
  inline void after_instruction() {
    const uint8_t i = avr_->sreg[S_I];
    if (i != ibit_) ibit_changed(i);
    if (fn_pc_ && (in_fn_ || avr_->pc == fn_pc_)) function_step();
  }
  void estop_edge(bool asserted);
  void flush();

 private:
  static void on_step(avr_irq_t* irq, uint32_t value, void* param);
  static void on_dir(avr_irq_t* irq, uint32_t value, void* param);
  static void on_vector(avr_irq_t* irq, uint32_t value, void* param);
  static void on_pending(avr_irq_t* irq, uint32_t value, void* param);
  static void on_ocr1a(avr_irq_t* irq, uint32_t value, void* param);
  static void on_tcnt1(avr_irq_t* irq, uint32_t value, void* param);
  static void on_tccr1b(avr_irq_t* irq, uint32_t value, void* param);
  uint32_t tcnt1() const;
  void ibit_changed(uint8_t i);
  void function_step();
  uint16_t sp() const { return static_cast<uint16_t>(avr_->data[R_SPL] | (avr_->data[R_SPH] << 8)); }

  static constexpr uint64_t kShortWindow = 24;
  uint64_t off_at_ = 0;      // cycle the I bit went to 0
  uint32_t off_pc_ = 0;      // program counter (bytes) of the instruction after it
  int off_ctx_ = -1;         // where: -1 main loop, else the running vector; + 100 when the vector's entry cleared it
  bool entered_ = false;     // a vector was entered since the last I-bit change
  int depth_vec_[16] = {};   // running vectors, innermost last
  int depth_ = 0;
  uint64_t short_count_ = 0, short_max_ = 0;

  // The timed function: every call is logged ("F"), and counted in the closing "f" line.
  uint32_t fn_pc_ = 0;
  bool in_fn_ = false;
  uint16_t fn_sp_ = 0;                          // SP at its first instruction (the return address just above)
  uint64_t fn_at_ = 0, fn_isr_ = 0, isr_at_ = 0;  // entry cycle, interrupt cycles inside it, outer interrupt's entry
  uint64_t fn_calls_ = 0;

  avr_t* avr_ = nullptr;
  std::FILE* out_ = nullptr;
  uint8_t ibit_ = 0;
  uint8_t step_[RBX1_JOINTS] = {}, dir_[RBX1_JOINTS] = {};
  uint64_t t1_zero_ = 0;   // cycle at which Timer1 last counted from 0 (compare match in CTC, TCNT1 write, start)
  uint8_t t1_div_ = 0;     // Timer1 prescaler (0: stopped)
};

}  // namespace rbx1::avrsim
