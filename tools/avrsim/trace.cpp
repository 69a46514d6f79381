// trace.cpp - the pin-level timing logger (trace.hpp): simavr IRQ hooks on the STEP/DIR pins, the vectors'
// "running" and "pending" IRQs, writes to OCR1A/TCNT1/TCCR1B, and the I bit polled after every instruction.
#include "trace.hpp"

#include <algorithm>

extern "C" {
#include "avr_ioport.h"
#include "sim_interrupts.h"
#include "sim_io.h"
}

#include "pinmap.hpp"

namespace rbx1::avrsim {
namespace {

// ATmega2560 data-space addresses of Timer1's registers and its compare A vector.
constexpr avr_io_addr_t kTCCR1B = 0x81, kTCNT1L = 0x84, kOCR1AL = 0x88;
constexpr int kTimer1CompA = 17;

struct Hook {
  Trace* trace;
  int index;
};

avr_irq_t* pin_irq(avr_t* avr, PortPin p) { return avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(p.port), p.bit); }

unsigned long long cyc(const avr_t* avr) { return static_cast<unsigned long long>(avr->cycle); }

}  // namespace

bool Trace::open(avr_t* avr, const std::string& path, std::string& error) {
  avr_ = avr;
  out_ = std::fopen(path.c_str(), "w");
  if (!out_) {
    error = path + ": cannot write the trace";
    return false;
  }
  static char buf[1 << 20];
  std::setvbuf(out_, buf, _IOFBF, sizeof buf);
  std::fprintf(out_, "# rbx1-avrsim trace 1: S cycle joint level | D cycle joint level | E/X/P cycle vector | "
                     "W cycle length where pc | O cycle ocr1a tcnt1 | K cycle level | w short_windows short_max | "
                     "F cycle cycles own_cycles | f calls\n");
  for (int j = 0; j < RBX1_JOINTS; j++) {
    avr_irq_register_notify(pin_irq(avr, kJoints[j].step), &Trace::on_step, new Hook{this, j});
    avr_irq_register_notify(pin_irq(avr, kJoints[j].dir), &Trace::on_dir, new Hook{this, j});
  }
  for (int i = 0; i < avr->interrupts.vector_count; i++) {
    avr_int_vector_t* v = avr->interrupts.vector[i];
    avr_irq_register_notify(v->irq + AVR_INT_IRQ_RUNNING, &Trace::on_vector, new Hook{this, v->vector});
    avr_irq_register_notify(v->irq + AVR_INT_IRQ_PENDING, &Trace::on_pending, new Hook{this, v->vector});
  }
  avr_irq_register_notify(avr_iomem_getirq(avr, kOCR1AL, nullptr, AVR_IOMEM_IRQ_ALL), &Trace::on_ocr1a, this);
  avr_irq_register_notify(avr_iomem_getirq(avr, kTCNT1L, nullptr, AVR_IOMEM_IRQ_ALL), &Trace::on_tcnt1, this);
  avr_irq_register_notify(avr_iomem_getirq(avr, kTCCR1B, nullptr, AVR_IOMEM_IRQ_ALL), &Trace::on_tccr1b, this);
  ibit_ = avr->sreg[S_I];
  return true;
}

void Trace::on_step(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Trace* t = h->trace;
  const uint8_t level = value & 1;
  if (level == t->step_[h->index]) return;  // simavr re-raises unchanged pins on every port write
  t->step_[h->index] = level;
  std::fprintf(t->out_, "S %llu %d %u\n", cyc(t->avr_), h->index, level);
}

void Trace::on_dir(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Trace* t = h->trace;
  const uint8_t level = value & 1;
  if (level == t->dir_[h->index]) return;
  t->dir_[h->index] = level;
  std::fprintf(t->out_, "D %llu %d %u\n", cyc(t->avr_), h->index, level);
}

void Trace::on_vector(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Trace* t = h->trace;
  if (value) {
    // simavr's own depth is the truth: a watchdog reset abandons interrupts without RETI.
    t->depth_ = std::min<int>(static_cast<int>(t->avr_->interrupts.running_ptr), 15);  // before this entry
    if (t->depth_ == 0) t->isr_at_ = t->avr_->cycle;
    t->depth_vec_[t->depth_++] = h->index;
    t->entered_ = true;
  } else if (t->depth_ > 0) {
    if (--t->depth_ == 0 && t->in_fn_) t->fn_isr_ += t->avr_->cycle - t->isr_at_;
  }
  std::fprintf(t->out_, "%c %llu %d\n", value ? 'E' : 'X', cyc(t->avr_), h->index);
}

// "W start cycles where pc": where is m (a cli in the main loop), c<v> (a cli inside vector v) or e<v> (vector v's
// entry: the hardware clears the I bit, its RETI or a sei sets it again).
void Trace::ibit_changed(uint8_t i) {
  ibit_ = i;
  if (!i) {
    off_at_ = avr_->cycle;
    off_pc_ = avr_->pc;
    if (entered_ && depth_ > 0)
      off_ctx_ = 100 + depth_vec_[depth_ - 1];
    else
      off_ctx_ = depth_ > 0 ? depth_vec_[depth_ - 1] : -1;
    entered_ = false;
    return;
  }
  entered_ = false;
  const uint64_t w = avr_->cycle - off_at_;
  if (w < kShortWindow) {
    short_count_++;
    short_max_ = std::max(short_max_, w);
    return;
  }
  if (off_ctx_ < 0)
    std::fprintf(out_, "W %llu %llu m %x\n", static_cast<unsigned long long>(off_at_),
                 static_cast<unsigned long long>(w), off_pc_);
  else
    std::fprintf(out_, "W %llu %llu %c%d %x\n", static_cast<unsigned long long>(off_at_),
                 static_cast<unsigned long long>(w), off_ctx_ >= 100 ? 'e' : 'c', off_ctx_ % 100, off_pc_);
}

// "F entry cycles own": the timed function from its first instruction to its return (the first instruction at which
// SP is back above the return address: the stack only grows below it meanwhile, interrupts included), and the same
// less the interrupts that ran inside it. Only main-loop calls count (none enters it in an interrupt).
void Trace::function_step() {
  if (!in_fn_) {
    if (depth_ > 0) return;
    in_fn_ = true;
    fn_sp_ = sp();
    fn_at_ = avr_->cycle;
    fn_isr_ = 0;
    return;
  }
  if (sp() <= fn_sp_) return;
  in_fn_ = false;
  fn_calls_++;
  const uint64_t wall = avr_->cycle - fn_at_, own = wall - fn_isr_;
  std::fprintf(out_, "F %llu %llu %llu\n", static_cast<unsigned long long>(fn_at_),
                 static_cast<unsigned long long>(wall), static_cast<unsigned long long>(own));
}

void Trace::on_pending(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Trace* t = h->trace;
  if (!value || h->index != kTimer1CompA) return;  // other flags rise with their interrupts disabled: not logged
  // In CTC mode the compare match that raises TIMER1_COMPA also clears TCNT1.
  t->t1_zero_ = t->avr_->cycle;
  std::fprintf(t->out_, "P %llu %d\n", cyc(t->avr_), h->index);
}

// Timer1's count now, from the cycle it last started from 0 and its prescaler (the firmware runs it at /8).
uint32_t Trace::tcnt1() const {
  if (!t1_div_) return 0;
  return static_cast<uint32_t>((avr_->cycle - t1_zero_) / t1_div_);
}

void Trace::on_ocr1a(avr_irq_t*, uint32_t, void* param) {
  auto* t = static_cast<Trace*>(param);
  const unsigned ocr = t->avr_->data[kOCR1AL] | (t->avr_->data[kOCR1AL + 1] << 8);
  std::fprintf(t->out_, "O %llu %u %u\n", cyc(t->avr_), ocr, t->tcnt1());
}

void Trace::on_tcnt1(avr_irq_t*, uint32_t, void* param) {
  auto* t = static_cast<Trace*>(param);
  const unsigned v = t->avr_->data[kTCNT1L] | (t->avr_->data[kTCNT1L + 1] << 8);
  t->t1_zero_ = t->avr_->cycle - static_cast<uint64_t>(v) * (t->t1_div_ ? t->t1_div_ : 8);
}

void Trace::on_tccr1b(avr_irq_t*, uint32_t value, void* param) {
  auto* t = static_cast<Trace*>(param);
  static const uint8_t kDiv[8] = {0, 1, 8, 64, 0, 0, 0, 0};  // 256/1024/external: not used by the firmware
  const uint8_t div = kDiv[value & 7];
  if (div && !t->t1_div_) t->t1_zero_ = t->avr_->cycle;  // the count resumes from TCNT1 (the firmware zeroes it)
  t->t1_div_ = div;
}

void Trace::estop_edge(bool asserted) { std::fprintf(out_, "K %llu %d\n", cyc(avr_), asserted ? 1 : 0); }

void Trace::flush() {
  if (!out_) return;
  std::fprintf(out_, "w %llu %llu\n", static_cast<unsigned long long>(short_count_),
               static_cast<unsigned long long>(short_max_));
  if (fn_pc_) std::fprintf(out_, "f %llu\n", static_cast<unsigned long long>(fn_calls_));
  std::fflush(out_);
}

}  // namespace rbx1::avrsim
