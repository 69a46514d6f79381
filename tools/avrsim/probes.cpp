// probes.cpp - STEP/DIR counting from pin-change IRQs, interrupt timing from simavr's vector "running" IRQs,
// e-stop latency, and UART0 request/response exchange times.
#include "probes.hpp"

#include <algorithm>

extern "C" {
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_interrupts.h"
#include "sim_io.h"
}

#include "pinmap.hpp"

namespace rbx1::avrsim {
namespace {

// A pulse seen this long (in cycles, 50 ms at 16 MHz) before an e-stop edge means the board was moving.
constexpr uint64_t kMovingWindow = 800000;

struct Hook {
  Probes* probe;
  int index;
};

avr_irq_t* pin_irq(avr_t* avr, PortPin p) {
  return avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(p.port), p.bit);
}

}  // namespace

void Probes::attach(avr_t* avr, int isr_vector) {
  avr_ = avr;
  forced_vector_ = isr_vector;
  for (int j = 0; j < RBX1_JOINTS; j++) {
    // Hooks live as long as the process; simavr only keeps the pointer.
    auto* step = new Hook{this, j};
    avr_irq_register_notify(pin_irq(avr, kJoints[j].step), &Probes::on_step, step);
    auto* en = new Hook{this, j};
    avr_irq_register_notify(pin_irq(avr, kJoints[j].en), &Probes::on_enable, en);
    enable_level_[j] = !kEnableActive;  // drivers off until the firmware drives EN
  }
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), &Probes::on_uart_in, this);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), &Probes::on_uart_out, this);
  // Every vector's "running" IRQ goes to 1 when the core jumps to it and to 0 at its RETI.
  for (int i = 0; i < avr->interrupts.vector_count; i++) {
    avr_int_vector_t* v = avr->interrupts.vector[i];
    auto* h = new Hook{this, v->vector};
    avr_irq_register_notify(v->irq + AVR_INT_IRQ_RUNNING, &Probes::on_vector, h);
  }
}

void Probes::on_reset() { running_.clear(); }

void Probes::on_uart_in(avr_irq_t*, uint32_t, void* param) {
  auto* p = static_cast<Probes*>(param);
  if (p->rx_bytes_++ == 0) p->first_rx_ = p->avr_->cycle;
  p->last_rx_ = p->avr_->cycle;
  if (p->in_request_ && !p->answered_) return;  // more bytes of the same request
  p->close_exchange();
  p->in_request_ = true;
  p->answered_ = false;
  p->request_start_ = p->avr_->cycle;
}

void Probes::on_uart_out(avr_irq_t*, uint32_t, void* param) {
  auto* p = static_cast<Probes*>(param);
  p->tx_bytes_++;
  p->last_tx_ = p->avr_->cycle;
  if (!p->in_request_) return;  // unsolicited output
  p->answered_ = true;
  p->last_out_ = p->avr_->cycle;
}

void Probes::close_exchange() {
  if (in_request_ && answered_) {
    exchanges_++;
    exchange_total_ += last_out_ - request_start_;
  }
  in_request_ = false;
  answered_ = false;
}

void Probes::on_step(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  h->probe->step_edge(h->index, value);
}

void Probes::step_edge(int j, uint32_t value) {
  uint8_t level = value & 1;
  if (level == step_level_[j]) return;  // simavr re-raises unchanged pins on every port write
  step_level_[j] = level;
  if (level != kStepActive) return;  // a pulse counts on its leading edge
  // DIR is read from the PORT register itself, so a DIR change in the same write is ordered correctly.
  const PortPin dir = kJoints[j].dir;
  uint8_t dir_level = (avr_->data[port_register(dir.port)] >> dir.bit) & 1;
  steps_[j] += dir_level == kDirPositive ? 1 : -1;
  pulses_[j]++;
  if (!any_pulse_) first_pulse_cycle_ = avr_->cycle;
  if (!window_any_) window_first_ = avr_->cycle;
  window_any_ = true;
  last_pulse_cycle_ = avr_->cycle;
  any_pulse_ = true;
  if (estop_open_) estop_last_pulse_ = avr_->cycle;
  if (!running_.empty()) {
    running_.back().pulses++;
    vectors_[running_.back().vector].pulses++;
  }
}

void Probes::on_enable(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Probes* p = h->probe;
  p->enable_level_[h->index] = value & 1;
  if (p->estop_open_ && !p->estop_disabled_at_ &&
      std::all_of(p->enable_level_.begin(), p->enable_level_.end(), [](uint8_t l) { return l != kEnableActive; }))
    p->estop_disabled_at_ = p->avr_->cycle;
}

void Probes::on_vector(avr_irq_t*, uint32_t value, void* param) {
  auto* h = static_cast<Hook*>(param);
  Probes* p = h->probe;
  if (value) {
    // simavr's own stack depth (before this entry) is the truth: a watchdog reset abandons calls without RETI.
    const size_t depth = p->avr_->interrupts.running_ptr;
    if (p->running_.size() > depth) p->running_.resize(depth);
    if (p->estop_open_ && !p->entry_after_edge_[h->index]) p->entry_after_edge_[h->index] = p->avr_->cycle;
    p->running_.push_back({static_cast<uint8_t>(h->index), p->avr_->cycle, 0});
    return;
  }
  if (p->running_.empty() || p->running_.back().vector != h->index) return;  // a RETI we did not see enter
  Running r = p->running_.back();
  p->running_.pop_back();
  uint64_t d = p->avr_->cycle - r.entry;
  VectorStats& s = p->vectors_[r.vector];
  s.count++;
  s.total += d;
  s.max = std::max(s.max, d);
  if (r.pulses) {
    s.step_calls++;
    s.step_total += d;
    s.step_max = std::max(s.step_max, d);
  }
  // A nested interrupt's time also counts in the one it interrupted, as it would on the real chip.
}

void Probes::on_estop_edge() {
  finish_estop_event();
  if (!any_pulse_ || avr_->cycle - last_pulse_cycle_ > kMovingWindow) return;  // not moving: nothing to stop
  estop_open_ = true;
  estop_edge_ = avr_->cycle;
  estop_last_pulse_ = 0;
  estop_disabled_at_ = 0;
  entry_after_edge_.fill(0);
  estop_events_++;
}

void Probes::finish_estop_event() {
  if (!estop_open_) return;
  estop_open_ = false;
  int64_t lat = estop_last_pulse_ ? static_cast<int64_t>(estop_last_pulse_ - estop_edge_) : 0;
  estop_worst_ = std::max(estop_worst_, lat);
  const int v = step_vector();
  if (v >= 0 && entry_after_edge_[v])
    estop_reaction_worst_ = std::max(estop_reaction_worst_, static_cast<int64_t>(entry_after_edge_[v] - estop_edge_));
  if (estop_disabled_at_)
    estop_disable_worst_ = std::max(estop_disable_worst_, static_cast<int64_t>(estop_disabled_at_ - estop_edge_));
}

int Probes::step_vector() const {
  if (forced_vector_ >= 0) return forced_vector_;
  int best = -1;
  uint64_t most = 0;
  for (int v = 0; v < 64; v++)
    if (vectors_[v].pulses > most) {
      most = vectors_[v].pulses;
      best = v;
    }
  return best;
}

nlohmann::json Probes::to_json() const {
  // Close the open e-stop event on a copy: to_json may be asked for while the board still runs.
  Probes copy = *this;
  copy.finish_estop_event();
  copy.close_exchange();
  nlohmann::json j;
  j["steps"] = steps_;
  j["pulses"] = pulses_;
  int v = step_vector();
  nlohmann::json isr = {{"vector", v < 0 ? nlohmann::json(nullptr) : nlohmann::json(v)}};
  const VectorStats s = v >= 0 ? vectors_[v] : VectorStats{};
  isr["count"] = s.count;
  isr["mean_cycles"] = s.count ? static_cast<double>(s.total) / s.count : 0.0;
  isr["max_cycles"] = s.max;
  isr["total_cycles"] = s.total;
  isr["step_calls"] = s.step_calls;
  isr["step_mean_cycles"] = s.step_calls ? static_cast<double>(s.step_total) / s.step_calls : 0.0;
  isr["step_max_cycles"] = s.step_max;
  isr["step_total_cycles"] = s.step_total;
  isr["pulses"] = s.pulses;
  j["isr"] = isr;
  nlohmann::json vecs = nlohmann::json::object();
  for (int i = 0; i < 64; i++)
    if (vectors_[i].count)
      vecs[std::to_string(i)] = {{"count", vectors_[i].count},
                                 {"mean_cycles", static_cast<double>(vectors_[i].total) / vectors_[i].count},
                                 {"max_cycles", vectors_[i].max}};
  j["vectors"] = vecs;
  j["estop_latency_cycles"] = copy.estop_worst_ >= 0 ? nlohmann::json(copy.estop_worst_) : nlohmann::json(nullptr);
  j["estop_disable_cycles"] =
      copy.estop_disable_worst_ >= 0 ? nlohmann::json(copy.estop_disable_worst_) : nlohmann::json(nullptr);
  j["estop_isr_reaction_cycles"] =
      copy.estop_reaction_worst_ >= 0 ? nlohmann::json(copy.estop_reaction_worst_) : nlohmann::json(nullptr);
  j["estop_events"] = copy.estop_events_;
  j["first_pulse_cycle"] = any_pulse_ ? nlohmann::json(first_pulse_cycle_) : nlohmann::json(nullptr);
  j["last_pulse_cycle"] = any_pulse_ ? nlohmann::json(last_pulse_cycle_) : nlohmann::json(nullptr);
  j["uart"] = {{"exchanges", copy.exchanges_},
               {"mean_exchange_cycles",
                copy.exchanges_ ? static_cast<double>(copy.exchange_total_) / copy.exchanges_ : 0.0},
               {"rx_bytes", rx_bytes_},
               {"tx_bytes", tx_bytes_},
               {"first_rx_cycle", rx_bytes_ ? nlohmann::json(first_rx_) : nlohmann::json(nullptr)},
               {"last_rx_cycle", rx_bytes_ ? nlohmann::json(last_rx_) : nlohmann::json(nullptr)},
               {"last_tx_cycle", tx_bytes_ ? nlohmann::json(last_tx_) : nlohmann::json(nullptr)}};
  j["window_first_pulse_cycle"] = window_any_ ? nlohmann::json(window_first_) : nlohmann::json(nullptr);
  j["cycles"] = avr_ ? avr_->cycle : 0;
  return j;
}

}  // namespace rbx1::avrsim
