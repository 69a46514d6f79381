// step_trace.hpp - every step pulse of the simulated board with its time and direction, and the joints' peak
// speeds and accelerations measured from them (the look-ahead and line timing tests).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "hal_sim.hpp"

namespace rbx1::fwtest {

constexpr double kHz = 2e6;  // simulated ticks per second

// Every pulse with its time and signed direction, every completed entry's time.
struct Trace {
  std::array<std::vector<std::pair<uint64_t, int>>, RBX1_JOINTS> steps;
  std::vector<uint64_t> done;
  void attach() {
    sim::board().on_step = [this](uint8_t mask, uint64_t now) {
      for (int i = 0; i < RBX1_JOINTS; i++)
        if (mask & (1u << i)) steps[i].push_back({now, (sim::board().dir_level >> i) & 1 ? 1 : -1});
    };
    sim::board().on_entry_done = [this](uint8_t, uint16_t, const int32_t*, const int32_t*, const int32_t*, uint16_t,
                                        uint16_t) { done.push_back(sim::board().now); };
  }
  // Every pulse of every joint, in time order.
  std::vector<uint64_t> all() const {
    std::vector<uint64_t> t;
    for (const auto& s : steps)
      for (const auto& p : s) t.push_back(p.first);
    std::sort(t.begin(), t.end());
    return t;
  }
  // Joint j's position (steps from the start) at tick t.
  int64_t position(int j, uint64_t t) const {
    int64_t p = 0;
    for (const auto& s : steps[j]) {
      if (s.first > t) break;
      p += s.second;
    }
    return p;
  }
};

struct Measured {
  double max_speed[RBX1_JOINTS] = {}, max_accel[RBX1_JOINTS] = {};
};

// Joint speeds and accelerations from the positions at 1 ms steps: speed over windows of kSpeedW, acceleration as
// the second difference over windows of kAccelW (each position is exact at its instant: the quantisation is within
// one step, so 1/W and 4/W^2 are the tolerances).
constexpr double kSpeedW = 0.02, kAccelW = 0.1;
inline Measured measure(const Trace& tr, uint64_t t0, uint64_t t1) {
  Measured m;
  const uint64_t ws = (uint64_t)(kSpeedW * kHz), wa = (uint64_t)(kAccelW * kHz), dt = (uint64_t)(kHz / 1000);
  for (int j = 0; j < RBX1_JOINTS; j++) {
    if (tr.steps[j].empty()) continue;
    std::vector<int64_t> p;  // position at t0 + k ms
    int64_t pos = 0;
    size_t i = 0;
    for (uint64_t t = t0; t <= t1; t += dt) {
      while (i < tr.steps[j].size() && tr.steps[j][i].first <= t) pos += tr.steps[j][i++].second;
      p.push_back(pos);
    }
    const size_t ks = ws / dt, ka = wa / dt;
    for (size_t k = 0; k + ks < p.size(); k++)
      m.max_speed[j] = std::max(m.max_speed[j], std::fabs((double)(p[k + ks] - p[k])) / kSpeedW);
    for (size_t k = 0; k + 2 * ka < p.size(); k++)
      m.max_accel[j] = std::max(
          m.max_accel[j], std::fabs((double)(p[k + 2 * ka] - 2 * p[k + ka] + p[k])) / (kAccelW * kAccelW));
  }
  return m;
}

inline void expect_within_limits(const Measured& m, const double vmax[RBX1_JOINTS], const double acc[RBX1_JOINTS]) {
  for (int j = 0; j < RBX1_JOINTS; j++) {
    EXPECT_LE(m.max_speed[j], vmax[j] + 1 / kSpeedW) << "J" << j + 1;
    EXPECT_LE(m.max_accel[j], acc[j] * 1.02 + 4 / (kAccelW * kAccelW)) << "J" << j + 1;
  }
}

}  // namespace rbx1::fwtest
