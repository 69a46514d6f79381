// test_stop_anywhere.cpp - a STOP at any instant of a streamed path (the look-ahead running on through joined
// moves) brings the arm to rest: IDLE within the deceleration's time, counters balanced, positions where the pulses
// left the joints. Swept over stop instants 3 ms apart and two sets of limits (the bundled ones and the fast test
// arm's of the end-to-end tests).
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

using Target = std::array<int32_t, RBX1_JOINTS>;

// A three-joint path of short joined moves whose joint rates change smoothly (as a straight line of the tool
// point does through the IK), then reverse.
std::vector<Target> path(int n) {
  std::vector<Target> out;
  for (int k = 1; k <= n; k++) {
    double s = (double)k / n;
    out.push_back({(int32_t)std::lround(3000 * std::sin(M_PI * s)), (int32_t)std::lround(2400 * s * s),
                   (int32_t)std::lround(-1800 * s), 0, (int32_t)std::lround(900 * std::sin(2 * M_PI * s)), 0});
  }
  return out;
}

class StopAnywhere : public Fw, public ::testing::WithParamInterface<std::array<int32_t, 2>> {};

TEST_P(StopAnywhere, ComesToRestWhereverTheStopFalls) {
  const int32_t vmax = GetParam()[0], acc = GetParam()[1];
  const std::vector<Target> p = path(120);
  // The stop's longest deceleration (from vmax at acc) plus the 1 ms ticks around it, with a margin for the
  // moves kept to decelerate through.
  const uint32_t rest_ms = (uint32_t)(1000.0 * vmax / acc) * 2 + 20;
  int stuck = 0;
  std::string first;
  for (uint32_t stop_ms = 1; stop_ms <= 1200; stop_ms += 3) {
    SetUp();
    ready();
    for (int j = 0; j < RBX1_JOINTS; j++) {
      ASSERT_EQ(config_set((uint8_t)j, RBX1_KEY_MAX_SPEED, vmax), RBX1_OK);
      ASSERT_EQ(config_set((uint8_t)j, RBX1_KEY_ACCEL, acc), RBX1_OK);
    }
    uint64_t t0 = sim::board().now;
    size_t k = 0;
    bool grip = false;
    while (sim::board().now - t0 < (uint64_t)stop_ms * sim::kTicksPerMs) {
      // A gripper entry in the middle of the path, as a pick queues one between its descent and its lift.
      uint8_t st = k >= p.size()                ? (uint8_t)RBX1_QUEUE_FULL
                   : k == p.size() / 3 && !grip ? gripper(1500, 150)
                                                : move(std::vector<int32_t>(p[k].begin(), p[k].end()), 0);
      if (st == RBX1_OK && k == p.size() / 3 && !grip) {
        grip = true;
        continue;
      }
      if (st == RBX1_OK)
        k++;
      else
        run_ms(1);
    }
    ASSERT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
    rbx1_status_resp s{};
    uint32_t t = 0;
    for (; t < 3000; t++) {
      run_ms(1);
      s = status();
      if (s.state != RBX1_STATE_STOPPING && s.state != RBX1_STATE_MOVING) break;
    }
    bool ok = s.state == RBX1_STATE_IDLE && t <= rest_ms &&
              s.moves_accepted == (uint16_t)(s.moves_done + s.moves_flushed) && s.queue_free == 16;
    for (int j = 0; j < RBX1_JOINTS; j++) ok = ok && s.position[j] == sim::board().net[j];
    if (!ok && stuck++ == 0)
      first = "STOP at " + std::to_string(stop_ms) + " ms (" + std::to_string(k) + " moves sent): state " +
              std::to_string(s.state) + " after " + std::to_string(t) + " ms, faults " + std::to_string(s.faults) +
              ", accepted " + std::to_string(s.moves_accepted) + " done " + std::to_string(s.moves_done) +
              " flushed " + std::to_string(s.moves_flushed) + ", queue_free " + std::to_string(s.queue_free);
  }
  EXPECT_EQ(stuck, 0) << "stops that did not come to rest within " << rest_ms << " ms; the first: " << first;
}

INSTANTIATE_TEST_SUITE_P(Limits, StopAnywhere,
                         ::testing::Values(std::array<int32_t, 2>{2000, 20000}, std::array<int32_t, 2>{20000, 200000}));

}  // namespace
}  // namespace rbx1::fwtest
