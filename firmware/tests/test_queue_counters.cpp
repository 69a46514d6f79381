// test_queue_counters.cpp - STATUS.moves_accepted and moves_flushed (PROTOCOL.md "Reconnecting"): every entry the
// queue took is counted once as completed, flushed or still queued, through STOP, heartbeat loss, ESTOP,
// refusals, duplicates and a power cycle.
#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

// accepted = done + flushed + queued, the identity a host relies on after a reconnect.
void expect_balanced(const rbx1_status_resp& s) {
  EXPECT_EQ((uint16_t)(s.moves_done + s.moves_flushed + (16 - s.queue_free)), s.moves_accepted)
      << "done " << s.moves_done << " flushed " << s.moves_flushed << " free " << (int)s.queue_free;
}

TEST_F(Fw, CountersStartAtZeroAndCountAcceptedEntriesOnly) {
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, 0);
  EXPECT_EQ(s.moves_flushed, 0);
  EXPECT_EQ(move({100, 0, 0, 0, 0, 0}), RBX1_DISABLED);  // refused: not counted
  ready();
  EXPECT_EQ(move({200000, 0, 0, 0, 0, 0}), RBX1_SOFT_LIMIT);
  EXPECT_EQ(gripper(100, 0), RBX1_BAD_ARG);
  EXPECT_EQ(move({1000, 0, 0, 0, 0, 0}), RBX1_OK);
  EXPECT_EQ(gripper(1500, 10), RBX1_OK);
  s = status();
  EXPECT_EQ(s.moves_accepted, 2);
  EXPECT_EQ(s.moves_flushed, 0);
  expect_balanced(s);
  run_until_idle();
  s = status();
  EXPECT_EQ(s.moves_accepted, 2);
  EXPECT_EQ(s.moves_done, 2);
  expect_balanced(s);
}

TEST_F(Fw, DuplicateMoveIsCountedOnce) {
  ready();
  rbx1_move_req q{};
  q.target[0] = 500;
  uint8_t p[RBX1_MOVE_REQ_LEN];
  auto frame = encode(take_seq(), RBX1_MSG_MOVE, p, rbx1_move_req_pack(&q, p));
  ASSERT_TRUE(exchange(frame).got);
  ASSERT_TRUE(exchange(frame).got);  // a retransmission: the remembered response, nothing queued
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, 1);
  expect_balanced(s);
}

TEST_F(Fw, StopCountsTheTruncatedAndTheQueuedEntriesAsFlushed) {
  ready();
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(gripper(1500, 0), RBX1_OK);
  run_ms(300);
  expect_balanced(status());
  ASSERT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_STOPPING);
  EXPECT_EQ(s.moves_flushed, 2);  // the waiting two at once; the executing one is still decelerating
  expect_balanced(s);
  run_until_idle();
  s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.moves_accepted, 3);
  EXPECT_EQ(s.moves_done, 0);
  EXPECT_EQ(s.moves_flushed, 3);  // the truncated move never completed
  expect_balanced(s);
}

TEST_F(Fw, HeartbeatLossAndEstopFlushesAreCounted) {
  ready();
  ASSERT_EQ(move({2000, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  for (int i = 0; i < 300 && status().moves_done < 1; i++) run_ms(10);  // the first completes, the second runs
  ASSERT_EQ(status().state, RBX1_STATE_MOVING);
  run_ms(2500);  // silence: heartbeat lost, controlled stop
  rbx1_status_resp s = status();
  EXPECT_TRUE(s.faults & RBX1_FAULT_HEARTBEAT_LOST);
  EXPECT_EQ(s.moves_done, 1);
  EXPECT_EQ(s.moves_flushed, 2);
  expect_balanced(s);
  ASSERT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  ASSERT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_OK);
  run_ms(200);
  ASSERT_EQ(simple(RBX1_MSG_ESTOP), RBX1_OK);
  s = status();
  EXPECT_EQ(s.moves_accepted, 5);
  EXPECT_EQ(s.moves_done, 1);
  EXPECT_EQ(s.moves_flushed, 4);
  expect_balanced(s);
}

TEST_F(Fw, PowerCycleStartsTheCountersAgain) {
  ready();
  ASSERT_EQ(move({100, 0, 0, 0, 0, 0}), RBX1_OK);
  run_until_idle();
  EXPECT_EQ(status().moves_accepted, 1);
  boot();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, 0);
  EXPECT_EQ(s.moves_done, 0);
  EXPECT_EQ(s.moves_flushed, 0);
  EXPECT_EQ(s.homed, 0);
}

}  // namespace
}  // namespace rbx1::fwtest
