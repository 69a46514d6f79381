// test_stop_restart.cpp - a controlled stop (heartbeat loss, STOP) at many points of a move, then CLEAR_FAULT and
// new (often very short) moves: each must start, end at its exact target and take no longer than planned.
#include <cstdlib>
#include <string>
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

struct Done {
  bool got = false;
  uint64_t at = 0;  // simulated tick of completion
  uint16_t planned_ms = 0;
  std::vector<int32_t> end;
};

// Drives a test's firmware through stops and recoveries (the fixture's TearDown drops the observer).
class Recovery {
 public:
  explicit Recovery(Fw& fw) : fw_(fw) {
    sim::board().on_entry_done = [this](uint8_t, uint16_t, const int32_t*, const int32_t*, const int32_t* end,
                                        uint16_t planned_ms, uint16_t) {
      done_.got = true;
      done_.at = sim::board().now;
      done_.planned_ms = planned_ms;
      done_.end.assign(end, end + 6);
    };
  }

  // MOVE to target from rest, polling STATUS every 5 ms (the heartbeat): it must end exactly at target within its
  // planned time plus the tick that starts it and the tick that completes it.
  void move_completes(const std::vector<int32_t>& target, const std::string& what, uint16_t duration_ms = 0) {
    SCOPED_TRACE(what + ": MOVE to " + std::to_string(target[0]) + "," + std::to_string(target[1]));
    done_ = Done{};
    uint16_t before = status().moves_done;
    uint64_t t0 = sim::board().now;
    ASSERT_EQ(fw_.move(target, duration_ms), RBX1_OK);
    for (int i = 0; i < 20000 && !done_.got; i++) {  // 100 s of simulated time at most
      run_ms(5);
      status();
    }
    ASSERT_TRUE(done_.got) << "the move never completed; STATUS state " << (int)status().state << " position "
                           << status().position[0];
    uint64_t took_ms = (done_.at - t0 + sim::kTicksPerMs - 1) / sim::kTicksPerMs;
    EXPECT_LE(took_ms, (uint64_t)done_.planned_ms + 3) << "planned " << done_.planned_ms << " ms";
    EXPECT_LE(done_.planned_ms, took_ms + 10) << "the planned time is a tight bound, not a guess";
    EXPECT_GE(took_ms, (uint64_t)duration_ms) << "an entry never completes before duration_ms";
    EXPECT_GE(done_.planned_ms, duration_ms);
    rbx1_status_resp s = status();
    EXPECT_EQ(s.state, RBX1_STATE_IDLE);
    EXPECT_EQ(s.moves_done, (uint16_t)(before + 1));
    for (int j = 0; j < RBX1_JOINTS; j++) {
      EXPECT_EQ(done_.end[j], target[j]) << "joint " << j + 1;
      EXPECT_EQ(s.position[j], target[j]) << "joint " << j + 1;
      EXPECT_EQ(sim::board().net[j], target[j]) << "joint " << j + 1 << ": pulses on the pins";
    }
  }

  // After a stop: at rest, then CLEAR_FAULT; the positions are where the pulses left the joints.
  void settle_and_clear(const std::string& what) {
    SCOPED_TRACE(what);
    uint64_t n = sim::board().pulses[0];
    run_ms(50);  // at rest: no further pulse
    EXPECT_EQ(sim::board().pulses[0], n);
    rbx1_status_resp s = status();
    EXPECT_EQ(s.queue_free, 16);
    for (int j = 0; j < RBX1_JOINTS; j++) EXPECT_EQ(s.position[j], sim::board().net[j]);
    EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
    s = status();
    EXPECT_EQ(s.state, RBX1_STATE_IDLE);
    EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, 0);
  }

  // The harness's sequence: back to 0, then small moves (1..3 steps, mixed joints), each exact and on time.
  void recover(const std::string& what) {
    move_completes({0, 0, 0, 0, 0, 0}, what);
    move_completes({1, 0, 0, 0, 0, 0}, what);
    move_completes({3, -1, 0, 0, 0, 0}, what);
    move_completes({0, 0, 0, 0, 0, 0}, what);
    move_completes({-2, 0, 0, 0, 0, 1}, what);
    move_completes({0, 0, 0, 0, 0, 0}, what);
  }

  Done done_;

 private:
  rbx1_status_resp status() { return fw_.status(); }
  void run_ms(uint32_t ms) { fw_.run_ms(ms); }
  uint8_t simple(uint8_t type) { return fw_.simple(type); }
  Fw& fw_;
};

// Heartbeat loss at many points of a slow move (the harness's heartbeat_loss check) and of a fast one, with slow
// and fast acceleration: the stop lands before the first step, in the ramp-up (the reported positions 3-13),
// between profile ticks, and in the cruise.
TEST_F(Fw, HeartbeatLossAnywhereThenClearFaultAndMoveToZero) {
  ready();
  Recovery r(*this);
  ASSERT_EQ(config_set(RBX1_GLOBAL_JOINT, RBX1_KEY_HEARTBEAT_MS, 100), RBX1_OK);
  int cases = 0, early = 0;
  for (int32_t accel : {500, 8000, 60000}) {
    ASSERT_EQ(config_set(0, RBX1_KEY_ACCEL, accel), RBX1_OK);
    for (uint16_t duration : {8000, 0}) {
      for (uint32_t silence_after_ms = 0; silence_after_ms <= 60; silence_after_ms += 3) {
        std::string what = "ACCEL " + std::to_string(accel) + ", duration " + std::to_string(duration) +
                           ", last request " + std::to_string(silence_after_ms) + " ms into the move";
        SCOPED_TRACE(what);
        ASSERT_EQ(move({4000, 0, 0, 0, 0, 0}, duration), RBX1_OK);
        if (silence_after_ms) {
          run_ms(silence_after_ms);
          simple(RBX1_MSG_HEARTBEAT);  // the last request: silence from here
        }
        run_ms(100 + 400);  // HEARTBEAT_MS, then the stop
        rbx1_status_resp s = status();
        ASSERT_EQ(s.state, RBX1_STATE_FAULT) << "position " << s.position[0];
        ASSERT_TRUE(s.faults & RBX1_FAULT_HEARTBEAT_LOST);
        ASSERT_LT(s.position[0], 4000);
        if (s.position[0] <= 13) early++;
        r.settle_and_clear(what);
        r.recover(what);
        if (HasFatalFailure()) return;
        cases++;
      }
    }
  }
  EXPECT_EQ(cases, 3 * 2 * 21);
  EXPECT_GE(early, 10);  // the reported situation (a stop within the first 13 steps) was covered
}

// STOP at every 0.5 ms of the first 40 ms of a move (before its first step, on it, between profile ticks), with a
// two-joint move so the Bresenham state is stopped mid-block too; then the same recovery moves.
TEST_F(Fw, StopVeryEarlyThenShortMovesEndExactlyOnTime) {
  ready();
  Recovery r(*this);
  int cases = 0;
  for (int32_t accel : {500, 8000}) {
    ASSERT_EQ(config_set(0, RBX1_KEY_ACCEL, accel), RBX1_OK);
    ASSERT_EQ(config_set(1, RBX1_KEY_ACCEL, accel), RBX1_OK);
    for (uint32_t quarter_ms = 0; quarter_ms <= 160; quarter_ms += 2) {
      std::string what = "ACCEL " + std::to_string(accel) + ", STOP " + std::to_string(quarter_ms / 4.0) +
                         " ms into the move";
      SCOPED_TRACE(what);
      ASSERT_EQ(move({4000, -1500, 0, 0, 0, 0}), RBX1_OK);
      for (uint32_t q = 0; q < quarter_ms; q++) {
        sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
        fw_loop();
      }
      ASSERT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
      run_until_idle(5000);
      rbx1_status_resp s = status();
      ASSERT_EQ(s.state, RBX1_STATE_IDLE);
      r.settle_and_clear(what);
      r.recover(what);
      if (HasFatalFailure()) return;
      cases++;
    }
  }
  EXPECT_EQ(cases, 2 * 81);
}

// The planned time (move log, planned_ms) bounds every profile, short or long, ramped or cruising, within 10 ms.
TEST_F(Fw, PlannedTimeBoundsTheProfileTightly) {
  ready();
  Recovery r(*this);
  for (int32_t accel : {500, 8000, 200000}) {
    for (int32_t vmax : {300, 4000, 20000}) {
      ASSERT_EQ(config_set(0, RBX1_KEY_ACCEL, accel), RBX1_OK);
      ASSERT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, vmax), RBX1_OK);
      int32_t at = 0;
      for (int32_t n : {1, 2, 3, 5, 13, 100, 1000, 10000}) {  // planned_ms is 16-bit: under 65 s
        at = at > 0 ? at - n : at + n;  // alternate directions
        r.move_completes({at, n / 3, 0, 0, 0, 0}, "ACCEL " + std::to_string(accel) + ", MAX_SPEED " +
                                                      std::to_string(vmax) + ", " + std::to_string(n) + " steps");
        if (HasFatalFailure()) return;
      }
    }
  }
  // Stretched by duration_ms: the motion is aimed to end by then, so the entry completes at duration_ms.
  ASSERT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, 4000), RBX1_OK);
  ASSERT_EQ(config_set(0, RBX1_KEY_ACCEL, 8000), RBX1_OK);
  int32_t at = 0;
  for (uint16_t duration : {300, 600, 1000, 5000}) {
    for (int32_t n : {13, 200, 1500}) {
      at = at > 0 ? at - n : at + n;
      r.move_completes({at, -n / 2, 0, 0, 0, 7}, std::to_string(n) + " steps in " + std::to_string(duration) + " ms",
                       duration);
      if (HasFatalFailure()) return;
      if (duration == 1000) {  // stretched to it, not longer
        EXPECT_EQ(r.done_.planned_ms, duration) << n << " steps";
      }
    }
  }
}

// A very short move queued while a controlled stop is still decelerating is refused (BUSY), and one sent right
// as the stop reaches rest starts normally.
TEST_F(Fw, MoveRightAfterStopReachesRestEndsExactlyOnTime) {
  ready();
  Recovery r(*this);
  for (uint32_t extra = 0; extra <= 20; extra++) {
    SCOPED_TRACE("MOVE " + std::to_string(extra) + " ms after STOPPING ended");
    ASSERT_EQ(move({4000, 0, 0, 0, 0, 0}), RBX1_OK);
    run_ms(60, true);
    ASSERT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
    EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_BUSY);  // STOPPING
    for (int i = 0; i < 4000 && status().state == RBX1_STATE_STOPPING; i++) {
      sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
      fw_loop();
    }
    run_ms(extra);
    r.move_completes({0, 0, 0, 0, 0, 0}, "after STOP");
    if (HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace rbx1::fwtest
