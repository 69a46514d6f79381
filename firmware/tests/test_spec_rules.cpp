// test_spec_rules.cpp - the rules PROTOCOL.md states for its once-open points, pinned on the firmware core: the
// inter-byte timeout, the byte after a frame, HELLO with held requests or a wrong length, probes and the heartbeat,
// HOME's checks and `homed` across an ESTOP.
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

bool is_nak(const Reply& r, uint8_t seq, uint8_t reason) {
  return r.type == RBX1_MSG_NAK && r.seq == seq && r.payload.size() == 1 && r.payload[0] == reason;
}

// "Receiving": the inter-byte timeout counts from the last byte received, not from SYNC.
TEST_F(Fw, InterByteTimeoutCountsFromTheLastByte) {
  std::vector<uint8_t> f = encode(take_seq(), RBX1_MSG_HEARTBEAT, nullptr, 0);
  frames_.clear();
  for (uint8_t b : f) {  // 10 bytes 30 ms apart: 270 ms from SYNC to the last byte, never 50 ms of silence
    send_bytes(&b, 1);
    run_ms(30);
  }
  ASSERT_EQ(frames_.size(), 1u);
  EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_HEARTBEAT));
}

// "Receiving": the byte right after a delivered frame starts a candidate however late it comes.
TEST_F(Fw, DamagedSyncAfterAFrameIsReadHoweverLate) {
  ASSERT_EQ(simple(RBX1_MSG_HEARTBEAT), RBX1_OK);
  run_ms(3000);  // 60 inter-byte timeouts of silence
  uint8_t seq = take_seq();
  std::vector<uint8_t> f = encode(seq, RBX1_MSG_HEARTBEAT, nullptr, 0);
  f[0] ^= 0xFF;  // SYNC damaged
  Reply r = exchange(f);
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HEARTBEAT));
  EXPECT_EQ(r.seq, seq);
}

// "Receiving": after a frame, a corrupt candidate that starts with a real 0xA5 is NAKed BAD_CRC; one whose first
// byte is not 0xA5 (a damaged SYNC) is dropped without a NAK.
TEST_F(Fw, CorruptFrameRightAfterAFrameIsNakedOnlyWithARealSync) {
  for (bool real_sync : {true, false}) {
    SCOPED_TRACE(real_sync ? "0xA5 first" : "damaged SYNC first");
    uint8_t seq = take_seq();
    std::vector<uint8_t> good = encode(seq, RBX1_MSG_HEARTBEAT, nullptr, 0);
    std::vector<uint8_t> bad = encode(0x43, RBX1_MSG_HEARTBEAT, nullptr, 0);  // no 0xA5 after its SYNC
    bad[4] ^= 0x01;  // two CRC bytes: one more than the parity corrects
    bad[6] ^= 0x01;
    if (!real_sync) bad[0] = 0x5A;
    good.insert(good.end(), bad.begin(), bad.end());
    send_run(good, 20);
    ASSERT_GE(frames_.size(), 1u);
    EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_HEARTBEAT));
    if (real_sync) {
      ASSERT_EQ(frames_.size(), 2u);
      EXPECT_TRUE(is_nak(frames_[1], 0x43, RBX1_BAD_CRC));
    } else {
      EXPECT_EQ(frames_.size(), 1u) << "a candidate without SYNC is dropped silently";
    }
  }
}

// "Window": a HELLO forgets the held requests without a NAK (an ESTOP NAKs them SEQ_GAP); none of them runs.
TEST_F(Fw, HelloForgetsHeldRequestsWithoutANak) {
  ready();
  uint8_t seq = take_seq();  // the next in order: left missing, so the MOVEs after it are held
  rbx1_move_req q{};
  q.target[0] = 300;
  uint8_t p[RBX1_MOVE_REQ_LEN];
  rbx1_move_req_pack(&q, p);
  send_run(encode((uint8_t)(seq + 1), RBX1_MSG_MOVE, p, RBX1_MOVE_REQ_LEN));
  send_run(encode((uint8_t)(seq + 2), RBX1_MSG_MOVE, p, RBX1_MOVE_REQ_LEN));
  ASSERT_EQ(frames_.size(), 1u);
  ASSERT_TRUE(is_nak(frames_[0], (uint8_t)(seq + 2), RBX1_HELD));
  uint8_t v = RBX1_PROTO_VERSION;
  send_run(encode(100, RBX1_MSG_HELLO, &v, 1), 20);
  ASSERT_EQ(frames_.size(), 1u) << "the HELLO's answer alone";
  EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_HELLO));
  send_run(encode(101, RBX1_MSG_STATUS, nullptr, 0), 20);  // the order continues at the HELLO's SEQ + 1
  ASSERT_EQ(frames_.size(), 1u);
  rbx1_status_resp s{};
  ASSERT_EQ(rbx1_status_resp_unpack(&s, frames_[0].payload.data(), (uint8_t)frames_[0].payload.size()), RBX1_OK);
  EXPECT_EQ(s.moves_accepted, 0) << "a held MOVE ran";
}

// "What the firmware does": a HELLO of a wrong length is answered BAD_LENGTH, every other field 0, and starts a
// session all the same.
TEST_F(Fw, HelloOfAWrongLengthIsAnsweredBadLengthAndStartsASession) {
  ASSERT_EQ(simple(RBX1_MSG_HEARTBEAT), RBX1_OK);  // SEQ 0, 1: the order expects 2
  ASSERT_EQ(simple(RBX1_MSG_HEARTBEAT), RBX1_OK);
  uint8_t two[2] = {RBX1_PROTO_VERSION, 0};
  Reply r = exchange(encode(60, RBX1_MSG_HELLO, two, 2));
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HELLO));
  ASSERT_EQ(r.payload.size(), (size_t)RBX1_HELLO_RESP_LEN);
  EXPECT_EQ(r.payload[0], RBX1_BAD_LENGTH);
  for (size_t i = 1; i < r.payload.size(); i++) EXPECT_EQ(r.payload[i], 0) << "field byte " << i;
  r = exchange(encode(61, RBX1_MSG_HEARTBEAT, nullptr, 0));  // in order after the HELLO: a session started
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HEARTBEAT));
}

// "Heartbeat": probes (TYPE 0x7F, no payload) are NAKed UNKNOWN_TYPE and do not feed the heartbeat.
TEST_F(Fw, ProbesDoNotFeedTheHeartbeat) {
  ready();
  ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
  for (int i = 0; i < 15; i++) {  // a probe every 200 ms for 3 s, no request
    Reply r = exchange(encode((uint8_t)(seq_ - 1), RBX1_MSG_NAK, nullptr, 0));
    ASSERT_TRUE(r.got);
    EXPECT_TRUE(is_nak(r, (uint8_t)(seq_ - 1), RBX1_UNKNOWN_TYPE));
    run_ms(200);
  }
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_HEARTBEAT_LOST);
}

// "HOME and SET_POSITION": the mask is checked before the drivers; disabled drivers answer DISABLED.
TEST_F(Fw, HomeChecksItsMaskBeforeTheDrivers) {
  EXPECT_EQ(home(0x40), RBX1_BAD_ARG);
  EXPECT_EQ(home(0), RBX1_DISABLED);
  EXPECT_EQ(home(RBX1_ALL_JOINTS_MASK), RBX1_DISABLED);
  EXPECT_EQ(status().state, RBX1_STATE_IDLE);
}

// "HOME and SET_POSITION": `homed` survives an ESTOP; a homing cut short leaves its joint unhomed, the others kept.
TEST_F(Fw, HomedSurvivesAnEstopButNotTheJointBeingHomed) {
  ready();
  ASSERT_EQ(simple(RBX1_MSG_ESTOP), RBX1_OK);
  EXPECT_EQ(status().homed, RBX1_ALL_JOINTS_MASK);
  ASSERT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  EXPECT_EQ(status().homed, RBX1_ALL_JOINTS_MASK);
  sim::board().switches[2] = {true, -5000, true};  // far: joint 3 is still seeking when the ESTOP comes
  ASSERT_EQ(home(1u << 2), RBX1_OK);
  run_ms(100);
  ASSERT_EQ(simple(RBX1_MSG_ESTOP), RBX1_OK);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_EQ(s.homed, RBX1_ALL_JOINTS_MASK & ~(1u << 2));
}

}  // namespace
}  // namespace rbx1::fwtest
