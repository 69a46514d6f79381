// link_faults.hpp - link fault injection for one direction of the simulated serial line: each byte may be
// corrupted, dropped, duplicated or delayed with the given per-byte probabilities.
#pragma once

#include <cstdint>
#include <deque>
#include <random>

namespace rbx1::sim {

struct FaultRates {
  double corrupt = 0, drop = 0, duplicate = 0, delay_rate = 0;
  double delay_ms = 0;
};

class LinkFaults {
 public:
  LinkFaults(const FaultRates& rates, uint64_t seed) : rates_(rates), rng_(seed) {}
  // A byte enters the line at now_ms.
  void push(uint8_t byte, double now_ms);
  // Bytes whose delivery time has come, in order.
  template <typename F>
  void deliver(double now_ms, F&& sink) {
    while (!queue_.empty() && queue_.front().at <= now_ms) {
      sink(queue_.front().byte);
      queue_.pop_front();
    }
  }
  void clear() { queue_.clear(); }
  uint64_t corrupted() const { return corrupted_; }
  uint64_t dropped() const { return dropped_; }

 private:
  bool chance(double p) { return p > 0 && std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  struct Item {
    double at;
    uint8_t byte;
  };
  FaultRates rates_;
  std::mt19937_64 rng_;
  std::deque<Item> queue_;
  double last_at_ = 0;
  uint64_t corrupted_ = 0, dropped_ = 0;
};

}  // namespace rbx1::sim
