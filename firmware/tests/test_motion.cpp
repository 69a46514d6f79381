// test_motion.cpp - coordinated moves (exact steps, common start and finish), trapezoid limits, duration, queue.
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

struct StepTrace {
  std::array<std::vector<uint64_t>, RBX1_JOINTS> t;  // tick of every pulse per joint
  std::vector<uint64_t> isr;              // tick of every pulse-bearing ISR
  void attach() {
    sim::board().on_step = [this](uint8_t mask, uint64_t now) {
      isr.push_back(now);
      for (int i = 0; i < RBX1_JOINTS; i++)
        if (mask & (1u << i)) t[i].push_back(now);
    };
  }
};

// Moves from 0 to target and checks every pulse of every joint against the exact Bresenham schedule.
void check_coordinated(Fw& fw, std::vector<int32_t> target, int dominant);

TEST_F(Fw, CoordinatedMoveEndsAtExactTargetsTogether) {
  ready();
  check_coordinated(*this, {1000, -2000, 300, 4000, 7, -1}, 3);
}

TEST_F(Fw, LongCoordinatedMoveRunsAsExactSegments) {
  ready();
  check_coordinated(*this, {40000, -33001, 7, 0, 1, 32767}, 0);  // n >= 32768: two segments, no gap
}

void check_coordinated(Fw& fw, std::vector<int32_t> target, int dominant) {
  StepTrace tr;
  tr.attach();
  ASSERT_EQ(fw.move(target), RBX1_OK);
  fw.run_until_idle();
  rbx1_status_resp s = fw.status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.moves_done, 1);
  uint32_t n = (uint32_t)std::abs(target[dominant]);
  ASSERT_EQ(tr.t[dominant].size(), n);
  for (int i = 0; i < RBX1_JOINTS; i++) {
    EXPECT_EQ(s.position[i], target[i]) << "joint " << i + 1;
    EXPECT_EQ(sim::board().net[i], target[i]) << "joint " << i + 1;  // pulses and DIR as the drivers see them
    EXPECT_EQ(sim::board().pulses[i], (uint64_t)std::abs(target[i])) << "no back and forth";
    uint32_t ni = (uint32_t)std::abs(target[i]);
    ASSERT_EQ(tr.t[i].size(), ni);
    if (ni == 0) continue;
    // Bresenham per segment of at most 32767 dominant ticks (one segment below that): segment [k0, k0 + m) gets
    // the joint's exact share floor((k0+m)*ni/n) - floor(k0*ni/n) of steps, and its k-th one comes on the
    // segment's tick ceil(k*m/inc): evenly spread, exact.
    uint32_t step = 0;
    for (uint64_t k0 = 0; k0 < n; k0 += 32767) {
      uint64_t m = std::min<uint64_t>(32767, n - k0);
      uint64_t inc = (k0 + m) * ni / n - k0 * ni / n;
      for (uint64_t k = 1; k <= inc; k++, step++) {
        uint64_t tick = k0 + (k * m + inc - 1) / inc;
        ASSERT_EQ(tr.t[i][step], tr.t[dominant][tick - 1]) << "joint " << i + 1 << " step " << step + 1;
      }
    }
    ASSERT_EQ(step, ni);
    // The block starts every joint in its first dominant-tick window (k = 1 above: tick ceil(n/ni)) and
    // finishes them all on the dominant joint's last tick: together within one ISR tick.
    EXPECT_EQ(tr.t[i].back(), tr.t[dominant].back()) << "joint " << i + 1;
  }
  sim::board().on_step = nullptr;
}

TEST_F(Fw, ConsecutiveMovesAndGripperComplete) {
  ready();
  std::vector<std::array<int32_t, RBX1_JOINTS>> done;
  sim::board().on_entry_done = [&](uint8_t kind, uint16_t, const int32_t*, const int32_t*, const int32_t* end,
                                   uint16_t, uint16_t) {
    if (kind == 0) done.push_back({end[0], end[1], end[2], end[3], end[4], end[5]});
  };
  ASSERT_EQ(move({100, 200, 300, 400, 500, 600}), RBX1_OK);
  ASSERT_EQ(gripper(1500, 50), RBX1_OK);
  ASSERT_EQ(move({-100, 0, 300, 0, 0, -600}), RBX1_OK);
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_done, 3);
  EXPECT_EQ(s.gripper_us, 1500);
  EXPECT_EQ(sim::board().servo_us, 1500);
  ASSERT_EQ(done.size(), 2u);
  EXPECT_EQ(done[0], (std::array<int32_t, RBX1_JOINTS>{100, 200, 300, 400, 500, 600}));
  EXPECT_EQ(done[1], (std::array<int32_t, RBX1_JOINTS>{-100, 0, 300, 0, 0, -600}));
  for (int i = 0; i < RBX1_JOINTS; i++) EXPECT_EQ(sim::board().net[i], s.position[i]);
}

// Rates between pulses: 2 MHz ticks -> steps/s.
std::vector<double> rates(const std::vector<uint64_t>& t) {
  std::vector<double> r;
  for (size_t k = 1; k < t.size(); k++) r.push_back(2e6 / (double)(t[k] - t[k - 1]));
  return r;
}

TEST_F(Fw, TrapezoidStaysWithinMaxSpeedAndAccel) {
  ready();
  const double vmax = 3000, acc = 6000;
  ASSERT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, (int32_t)vmax), RBX1_OK);
  ASSERT_EQ(config_set(0, RBX1_KEY_ACCEL, (int32_t)acc), RBX1_OK);
  StepTrace tr;
  tr.attach();
  ASSERT_EQ(move({15000, 0, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  ASSERT_EQ(tr.t[0].size(), 15000u);
  std::vector<double> r = rates(tr.t[0]);
  double peak = 0;
  const double v0 = std::sqrt(acc / 2);  // the planned start/stop rate: first step 1/v0 after the start
  const double t0 = (double)tr.t[0].front() / 2e6 - 1 / v0, t1 = (double)tr.t[0].back() / 2e6;
  const double slack = acc / 1000.0;  // the rate changes once per 1 ms profile tick, by up to acc * 1 ms
  for (size_t k = 0; k < r.size(); k++) {
    double ta = (double)tr.t[0][k] / 2e6;  // the interval's start
    peak = std::max(peak, r[k]);
    ASSERT_LE(r[k], vmax * 1.01) << "step " << k;
    // Up from v0 at the start no faster than acc.
    ASSERT_LE(r[k], (v0 + acc * (ta - t0)) * 1.005 + slack) << "step " << k;
    // Step to step, the rate changes by at most acc over the time between them (plus one tick's change).
    if (k + 1 < r.size()) {
      double dt = (double)(tr.t[0][k + 2] - tr.t[0][k]) / 2e6;
      ASSERT_LE(std::fabs(r[k + 1] - r[k]), acc * dt * 1.01 + slack + 1) << "step " << k;
    }
  }
  // It ends at rest, not from speed: the last interval runs at the start/stop rate, mirroring the first, and
  // the ramp-down stays inside the envelope v^2 = v0^2 + 2 a s of the steps s still to go.
  EXPECT_NEAR(r.back(), v0, 0.02 * v0);
  EXPECT_NEAR(r.front(), std::sqrt(v0 * v0 + 2 * acc), 0.05 * v0);
  for (size_t k = 0; k < r.size(); k++) {
    double to_go = (double)(r.size() - 1 - k);  // steps after the one that ends interval k
    ASSERT_LE(r[k], std::sqrt(v0 * v0 + 2 * acc * to_go) * 1.005 + slack) << "step " << k;
  }
  (void)t1;
  EXPECT_GE(peak, vmax * 0.97);  // and it does reach the cruise speed
  // Time of the ideal trapezoid: n/v + v/a = 5.5 s.
  EXPECT_NEAR(t1 - t0, 15000 / vmax + vmax / acc, 0.1);
}

TEST_F(Fw, SlowJointLimitsTheDominantJoint) {
  ready();
  ASSERT_EQ(config_set(1, RBX1_KEY_MAX_SPEED, 1000), RBX1_OK);  // J2 moves half as far but is slow
  StepTrace tr;
  tr.attach();
  ASSERT_EQ(move({10000, 5000, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  ASSERT_EQ(tr.t[1].size(), 5000u);
  // J2's rate averaged over 20 of its steps never exceeds its own 1000 steps/s.
  for (size_t k = 20; k < tr.t[1].size(); k++)
    ASSERT_LE(20 * 2e6 / (double)(tr.t[1][k] - tr.t[1][k - 20]), 1000 * 1.01) << "J2 step " << k;
}

TEST_F(Fw, MoveIsNotShorterThanDuration) {
  ready();
  StepTrace tr;
  tr.attach();
  uint64_t t_start = sim::board().now;
  ASSERT_EQ(move({200, 100, 0, 0, 0, 0}, 1500), RBX1_OK);
  uint32_t ms = run_until_idle();
  EXPECT_GE((double)(tr.t[0].back() - t_start) / 2000.0, 1500 * 0.9);  // the profile is stretched, not padded
  EXPECT_GE(ms, 1500u);
  EXPECT_LE(ms, 1600u);
  EXPECT_EQ(status().moves_done, 1);
}

TEST_F(Fw, QueueFullIsRefused) {
  ready();
  uint8_t free_slots = 0;
  for (int i = 0; i < 16; i++) {
    ASSERT_EQ(gripper(1000 + 10 * i, 1000, &free_slots), RBX1_OK) << i;
    EXPECT_EQ(free_slots, 15 - i);
  }
  EXPECT_EQ(gripper(1200, 10, &free_slots), RBX1_QUEUE_FULL);
  EXPECT_EQ(free_slots, 0);
  EXPECT_EQ(move({10, 0, 0, 0, 0, 0}, 0, &free_slots), RBX1_QUEUE_FULL);
  run_ms(1100, true);  // the first entry completes: room for one
  EXPECT_EQ(status().moves_done, 1);
  EXPECT_EQ(move({10, 0, 0, 0, 0, 0}, 0, &free_slots), RBX1_OK);
  EXPECT_EQ(free_slots, 0);
}

TEST_F(Fw, InvertDirFlipsTheDirPinNotThePosition) {
  ready();
  ASSERT_EQ(config_set(1, RBX1_KEY_INVERT_DIR, 1), RBX1_OK);
  ASSERT_EQ(move({100, 100, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.position[0], 100);
  EXPECT_EQ(s.position[1], 100);
  EXPECT_EQ(sim::board().net[0], 100);
  EXPECT_EQ(sim::board().net[1], -100);  // the motor of J2 is wired the other way round
}

TEST_F(Fw, GripperPulseOutsideLimitsIsBadArg) {
  ready();
  EXPECT_EQ(gripper(999, 0), RBX1_BAD_ARG);
  EXPECT_EQ(gripper(2001, 0), RBX1_BAD_ARG);
  EXPECT_EQ(gripper(2000, 0), RBX1_OK);
  run_ms(5);
  EXPECT_EQ(sim::board().servo_us, 2000);
}

}  // namespace
}  // namespace rbx1::fwtest
