// test_safety.cpp - refusals (DISABLED, NOT_HOMED, SOFT_LIMIT, BUSY), e-stop input and message latch, limit hit,
// heartbeat loss, controlled stop, watchdog reset report.
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

TEST_F(Fw, PowerUpIsDisabledAndNotHomed) {
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.enabled, 0);
  EXPECT_EQ(s.homed, 0);
  EXPECT_EQ(sim::board().drivers_on, 0);
  EXPECT_EQ(move({10, 0, 0, 0, 0, 0}), RBX1_DISABLED);
  EXPECT_EQ(home(0), RBX1_DISABLED);
  ASSERT_EQ(enable(1), RBX1_OK);
  EXPECT_EQ(sim::board().drivers_on, 1);
  EXPECT_EQ(move({10, 0, 0, 0, 0, 0}), RBX1_NOT_HOMED);
  EXPECT_EQ(gripper(1500, 0), RBX1_NOT_HOMED);
  run_ms(50);
  EXPECT_EQ(sim::board().pulses[0], 0u);
  EXPECT_EQ(status().queue_free, 16);
  ASSERT_EQ(set_position({5, 0, 0, 0, 0, 0}), RBX1_OK);
  EXPECT_EQ(status().homed, RBX1_ALL_JOINTS_MASK);
  EXPECT_EQ(move({10, 0, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  EXPECT_EQ(status().position[0], 10);
  EXPECT_EQ(sim::board().net[0], 5);  // 5 pulses from the declared 5
}

TEST_F(Fw, SoftLimitRejectsTheWholeMove) {
  ready();
  ASSERT_EQ(config_set(2, RBX1_KEY_SOFT_MAX, 500), RBX1_OK);
  ASSERT_EQ(config_set(2, RBX1_KEY_SOFT_MIN, -20), RBX1_OK);
  EXPECT_EQ(move({1000, 0, 501, 0, 0, 0}), RBX1_SOFT_LIMIT);
  EXPECT_EQ(move({1000, 0, -21, 0, 0, 0}), RBX1_SOFT_LIMIT);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 100001}), RBX1_SOFT_LIMIT);  // default limits +-100000
  run_ms(20);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.queue_free, 16);
  for (int i = 0; i < RBX1_JOINTS; i++) EXPECT_EQ(sim::board().pulses[i], 0u);
  EXPECT_EQ(move({1000, 0, 500, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  EXPECT_EQ(status().position[2], 500);
}

TEST_F(Fw, SetPositionOutsideTheSoftLimitsIsRefused) {
  ASSERT_EQ(enable(1), RBX1_OK);
  ASSERT_EQ(config_set(3, RBX1_KEY_SOFT_MAX, 500), RBX1_OK);
  EXPECT_EQ(set_position({0, 0, 0, 501, 0, 0}), RBX1_SOFT_LIMIT);
  EXPECT_EQ(set_position({-100001, 0, 0, 0, 0, 0}), RBX1_SOFT_LIMIT);  // default limits +-100000
  rbx1_status_resp s = status();
  EXPECT_EQ(s.homed, 0) << "a refused declaration changes nothing";
  for (int i = 0; i < RBX1_JOINTS; i++) EXPECT_EQ(s.position[i], 0);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_NOT_HOMED);
  EXPECT_EQ(set_position({-100000, 0, 0, 500, 0, 0}), RBX1_OK);  // the limits themselves are inside
  s = status();
  EXPECT_EQ(s.homed, RBX1_ALL_JOINTS_MASK);
  EXPECT_EQ(s.position[0], -100000);
  EXPECT_EQ(s.position[3], 500);
}

TEST_F(Fw, EstopInputStopsPulsesAtOnceAndLatches) {
  ready();
  uint64_t last_pulse = 0;
  sim::board().on_step = [&](uint8_t, uint64_t t) { last_pulse = t; };
  ASSERT_EQ(move({20000, 20000, 0, 0, 0, 0}), RBX1_OK);
  run_ms(300);
  ASSERT_GT(sim::board().pulses[0], 0u);
  sim::board().estop = true;
  uint64_t edge = sim::board().now;
  run_ms(100);
  EXPECT_LE(last_pulse, edge) << "a pulse after the e-stop edge";
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_ESTOP_INPUT);
  EXPECT_TRUE(s.inputs & RBX1_INPUT_ESTOP);
  EXPECT_EQ(s.queue_free, 16);
  EXPECT_EQ(s.position[0], sim::board().net[0]);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_FAULT_ACTIVE);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_ESTOP_ACTIVE);
  EXPECT_EQ(status().state, RBX1_STATE_FAULT);
  sim::board().estop = false;
  run_ms(5);
  EXPECT_EQ(status().state, RBX1_STATE_FAULT) << "the fault stays latched after the input releases";
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, 0);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  EXPECT_EQ(sim::board().net[0], 0);
}

TEST_F(Fw, EstopMessageStopsPulsesAtOnceAndIsNeverDeduplicated) {
  ready();
  uint64_t last_pulse = 0;
  sim::board().on_step = [&](uint8_t, uint64_t t) { last_pulse = t; };
  ASSERT_EQ(move({0, 0, 30000, 0, 0, 0}), RBX1_OK);
  run_ms(300);
  // A STATUS that the ESTOP will follow: its retransmission must still hit the cache (ESTOP is not recorded).
  std::vector<uint8_t> st = encode(take_seq(), RBX1_MSG_STATUS, nullptr, 0);
  Reply before = exchange(st);
  ASSERT_TRUE(before.got);
  std::vector<uint8_t> es = encode(201, RBX1_MSG_ESTOP, nullptr, 0);  // any SEQ: outside the window
  frames_.clear();
  send_bytes(es.data(), es.size());
  sim::run_until(sim::board().now + 1);
  fw_loop();  // the frame is handled in this main-loop pass
  uint64_t handled = sim::board().now;
  run_ms(50);
  EXPECT_LE(last_pulse, handled);
  ASSERT_FALSE(frames_.empty());
  EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_ESTOP));
  EXPECT_EQ(frames_[0].payload[0], RBX1_OK);
  Reply again = exchange(st);
  EXPECT_EQ(again.payload, before.payload) << "STATUS retransmission answered from the cache";
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_ESTOP_COMMAND);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  EXPECT_EQ(status().state, RBX1_STATE_IDLE);
  // The same ESTOP frame again (same SEQ and CRC): executed again, the fault latches again.
  Reply r = exchange(es);
  EXPECT_EQ(r.payload[0], RBX1_OK);
  EXPECT_TRUE(status().faults & RBX1_FAULT_ESTOP_COMMAND);
}

TEST_F(Fw, LimitSwitchHitWhileMovingIsAFault) {
  ready();
  uint64_t last_pulse = 0;
  sim::board().on_step = [&](uint8_t, uint64_t t) { last_pulse = t; };
  ASSERT_EQ(move({0, 0, 0, 0, 20000, 0}), RBX1_OK);
  run_ms(300);
  sim::board().limits = RBX1_INPUT_LIMIT_J2;
  uint64_t edge = sim::board().now;
  run_ms(50);
  EXPECT_LE(last_pulse, edge + sim::kTicksPerMs) << "steps must end within the 1 ms profile tick";
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_LIMIT_HIT);
  EXPECT_EQ(s.inputs & RBX1_ALL_JOINTS_MASK, RBX1_INPUT_LIMIT_J2);
  EXPECT_EQ(s.position[4], sim::board().net[4]);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  // A switch already pressed when a move starts is not a new hit (the arm may move off it).
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  EXPECT_EQ(status().state, RBX1_STATE_IDLE);
  EXPECT_EQ(sim::board().net[4], 0);
}

TEST_F(Fw, HeartbeatLossStopsUnderControlAndLatches) {
  ready();
  std::vector<uint64_t> t;
  sim::board().on_step = [&](uint8_t m, uint64_t now) {
    if (m & 1) t.push_back(now);
  };
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  run_ms(900);  // no request from the host...
  EXPECT_EQ(status().state, RBX1_STATE_MOVING);
  run_ms(1700);  // ... for 1000 ms after that STATUS, then 0.5 s of deceleration
  rbx1_status_resp s = status();
  ASSERT_NE(s.position[0], 60000);
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_HEARTBEAT_LOST);
  EXPECT_EQ(s.queue_free, 16);
  EXPECT_EQ(s.position[0], sim::board().net[0]);
  // Controlled: the last intervals grow (deceleration), it did not stop from full speed.
  ASSERT_GT(t.size(), 100u);
  double last = 2e6 / (double)(t[t.size() - 1] - t[t.size() - 2]);
  double cruise = 2e6 / (double)(t[t.size() / 2] - t[t.size() / 2 - 1]);
  EXPECT_GT(cruise, 3900);
  EXPECT_LT(last, 200);
  uint64_t n = sim::board().pulses[0];
  run_ms(200);
  EXPECT_EQ(sim::board().pulses[0], n);
}

TEST_F(Fw, SilenceInFaultAddsNoHeartbeatLost) {
  ready();
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  run_ms(100);
  ASSERT_EQ(simple(RBX1_MSG_ESTOP), RBX1_OK);
  run_ms(3000);  // three heartbeats of silence in FAULT
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, RBX1_FAULT_ESTOP_COMMAND);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  run_ms(3000);  // and in IDLE
  EXPECT_EQ(status().faults & RBX1_FAULTS_LATCHING, 0);
}

TEST_F(Fw, StopDeceleratesFlushesAndGoesIdle) {
  ready();
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  run_ms(500);
  EXPECT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
  EXPECT_EQ(status().state, RBX1_STATE_STOPPING);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_BUSY);
  run_ms(800);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, 0);
  EXPECT_EQ(s.queue_free, 16);
  EXPECT_EQ(s.moves_done, 0);
  EXPECT_GT(s.position[0], 0);
  EXPECT_LT(s.position[0], 60000);
  EXPECT_EQ(s.position[0], sim::board().net[0]);
}

TEST_F(Fw, EstopHeldAtPowerUpLatchesAtOnce) {
  sim::board().estop = true;
  boot();
  run_ms(3);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_ESTOP_INPUT);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_ESTOP_ACTIVE);
  sim::board().estop = false;
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  EXPECT_EQ(status().state, RBX1_STATE_IDLE);
}

TEST_F(Fw, WatchdogResetIsReported) {
  sim::board().watchdog_reset = true;
  boot();
  EXPECT_TRUE(status().faults & RBX1_FAULT_WATCHDOG_RESET);
  EXPECT_EQ(status().state, RBX1_STATE_IDLE);  // informational, not latching
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  EXPECT_FALSE(status().faults & RBX1_FAULT_WATCHDOG_RESET);
}

TEST_F(Fw, RequestsOutsideTheirStatesAreRefused) {
  ready();
  ASSERT_EQ(move({0, 0, 0, 8000, 0, 0}), RBX1_OK);
  run_ms(100);
  EXPECT_EQ(enable(0), RBX1_BUSY);
  EXPECT_EQ(set_position({0, 0, 0, 0, 0, 0}), RBX1_BUSY);
  EXPECT_EQ(config_set(0, RBX1_KEY_ACCEL, 100), RBX1_BUSY);
  EXPECT_EQ(home(0), RBX1_BUSY);
  EXPECT_EQ(simple(RBX1_MSG_ESTOP), RBX1_OK);
  EXPECT_EQ(set_position({0, 0, 0, 0, 0, 0}), RBX1_FAULT_ACTIVE);
  EXPECT_EQ(enable(0), RBX1_OK);  // allowed in FAULT
  EXPECT_EQ(sim::board().drivers_on, 0);
}

}  // namespace
}  // namespace rbx1::fwtest
