// link_faults.cpp - per-byte fault injection (order is kept: a delayed byte holds back the ones after it).
#include "link_faults.hpp"

#include <algorithm>

namespace rbx1::sim {

void LinkFaults::push(uint8_t byte, double now_ms) {
  if (chance(rates_.drop)) {
    dropped_++;
    return;
  }
  if (chance(rates_.corrupt)) {
    byte ^= (uint8_t)std::uniform_int_distribution<int>(1, 255)(rng_);
    corrupted_++;
  }
  double at = now_ms + (chance(rates_.delay_rate) ? rates_.delay_ms : 0.0);
  at = std::max(at, last_at_);
  last_at_ = at;
  queue_.push_back({at, byte});
  if (chance(rates_.duplicate)) queue_.push_back({at, byte});
}

}  // namespace rbx1::sim
