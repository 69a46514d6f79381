// test_link.cpp - the link: the window (duplicates answered from memory and not re-executed, requests ahead of a gap
// held and run in order once it is filled, old frames refused), garbage and corrupt frames NAKed (or ignored) with nothing executed, resynchronisation, HELLO.
#include <vector>

#include "fw_fixture.hpp"
#include "rbx1_window.h"

namespace rbx1::fwtest {
namespace {

std::vector<uint8_t> move_payload(std::vector<int32_t> target, uint16_t duration_ms = 0) {
  rbx1_move_req q{};
  for (int i = 0; i < RBX1_JOINTS; i++) q.target[i] = target[i];
  q.duration_ms = duration_ms;
  std::vector<uint8_t> p(RBX1_MOVE_REQ_LEN);
  rbx1_move_req_pack(&q, p.data());
  return p;
}

TEST_F(Fw, HelloReportsVersionsSizesAndCapabilities) {
  uint8_t p[1] = {RBX1_PROTO_VERSION};
  Reply r = request(RBX1_MSG_HELLO, p, 1);
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HELLO));
  rbx1_hello_resp h{};
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
  EXPECT_EQ(h.status, RBX1_OK);
  EXPECT_EQ(h.joints, 6);
  EXPECT_EQ(h.queue_size, 16);
  EXPECT_EQ(h.last_seq, 0xFF);  // nothing executed since power-up
  EXPECT_EQ(h.window, RBX1_WINDOW);
  EXPECT_EQ(h.capabilities & RBX1_CAP_SIMULATED, RBX1_CAP_SIMULATED);
  EXPECT_EQ(simple(RBX1_MSG_HEARTBEAT), RBX1_OK);  // seq 1
  r = request(RBX1_MSG_HELLO, p, 1);                // seq 2
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
  EXPECT_EQ(h.last_seq, 1);
  p[0] = RBX1_PROTO_VERSION + 1;
  r = request(RBX1_MSG_HELLO, p, 1);
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
  EXPECT_EQ(h.status, RBX1_BAD_VERSION);
  EXPECT_EQ(h.proto_version, RBX1_PROTO_VERSION);
}

// A host of protocol version 4 sends frames without parity: the firmware reads them at their CRC and answers its
// HELLO BAD_VERSION with version 5, each time it asks (its next HELLO after its 100 ms timeout).
TEST_F(Fw, Version4HostIsAnsweredBadVersion) {
  for (uint8_t seq = 0; seq < 2; seq++) {
    uint8_t p[1] = {4};
    std::vector<uint8_t> f = encode(seq, RBX1_MSG_HELLO, p, 1);
    f.resize(f.size() - RBX1_FEC_BYTES);
    Reply r = exchange(f);
    ASSERT_TRUE(r.got) << "HELLO " << int(seq);
    EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HELLO));
    EXPECT_EQ(r.seq, seq);
    rbx1_hello_resp h{};
    ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
    EXPECT_EQ(h.status, RBX1_BAD_VERSION);
    EXPECT_EQ(h.proto_version, RBX1_PROTO_VERSION);
    run_ms(100);
  }
}

TEST_F(Fw, DuplicateMoveIsAnsweredAgainButExecutedOnce) {
  ready();
  std::vector<uint8_t> p = move_payload({500, 0, 0, 0, 0, 0});
  uint8_t seq = take_seq();
  std::vector<uint8_t> f = encode(seq, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());
  Reply a = exchange(f);
  Reply b = exchange(f);
  ASSERT_TRUE(a.got);
  ASSERT_TRUE(b.got);
  EXPECT_EQ(a.seq, seq);
  EXPECT_EQ(b.seq, seq);
  EXPECT_EQ(a.payload, b.payload);
  EXPECT_EQ(status().queue_free, 15);
  run_until_idle();
  EXPECT_EQ(status().moves_done, 1);
  // Same SEQ, other content: a used SEQ, refused (SEQ_OLD) and never executed.
  std::vector<uint8_t> p2 = move_payload({0, 0, 0, 0, 0, 0});
  Reply c = exchange(encode(seq, RBX1_MSG_MOVE, p2.data(), (uint8_t)p2.size()));
  ASSERT_TRUE(c.got);
  EXPECT_EQ(c.type, RBX1_MSG_NAK);
  EXPECT_EQ(c.payload[0], RBX1_SEQ_OLD);
  run_until_idle();
  EXPECT_EQ(status().moves_done, 1);
  EXPECT_EQ(sim::board().pulses[0], 500u);
}

TEST_F(Fw, WindowFramesAreRunInOrderOnceAndOldOnesRefused) {
  ready();
  // Eight MOVEs back to back (a full window in flight), each one step further on joint 1.
  std::vector<std::vector<uint8_t>> frames;
  uint8_t first = take_seq();
  for (int i = 0; i < RBX1_WINDOW; i++) {
    std::vector<uint8_t> p = move_payload({(i + 1) * 10, 0, 0, 0, 0, 0});
    frames.push_back(encode(static_cast<uint8_t>(first + i), RBX1_MSG_MOVE, p.data(), (uint8_t)p.size()));
    if (i) take_seq();
  }
  frames_.clear();
  for (const auto& f : frames) send_bytes(f.data(), f.size());
  run_ms(5);
  ASSERT_EQ(frames_.size(), (size_t)RBX1_WINDOW);
  for (int i = 0; i < RBX1_WINDOW; i++) {
    EXPECT_EQ(frames_[i].seq, (uint8_t)(first + i));
    EXPECT_EQ(frames_[i].payload[0], RBX1_OK);
  }
  auto answers = frames_;
  // Every one of them again (a go-back), oldest first: answered from the window, nothing runs again.
  frames_.clear();
  for (const auto& f : frames) send_bytes(f.data(), f.size());
  run_ms(5);
  ASSERT_EQ(frames_.size(), (size_t)RBX1_WINDOW);
  for (int i = 0; i < RBX1_WINDOW; i++) EXPECT_EQ(frames_[i].payload, answers[i].payload);
  EXPECT_EQ(simple(RBX1_MSG_HEARTBEAT), RBX1_OK);  // a ninth request: the first MOVE leaves the window
  Reply old = exchange(frames[0]);
  ASSERT_TRUE(old.got);
  EXPECT_EQ(old.type, RBX1_MSG_NAK);
  EXPECT_EQ(old.payload[0], RBX1_SEQ_OLD);
  Reply kept = exchange(frames[1]);  // still remembered
  EXPECT_EQ(kept.type, RBX1_RESPONSE(RBX1_MSG_MOVE));
  EXPECT_EQ(kept.payload, answers[1].payload);
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, RBX1_WINDOW);
  EXPECT_EQ(s.position[0], RBX1_WINDOW * 10);
  EXPECT_EQ(sim::board().pulses[0], (uint64_t)RBX1_WINDOW * 10);
  // A gap: the request after the next one is held (NAK HELD) and not run; the missing one runs, then the held one.
  std::vector<uint8_t> pa = move_payload({0, 0, 0, 0, 0, 0}), pb = move_payload({5, 0, 0, 0, 0, 0});
  uint8_t sa = take_seq(), sb = take_seq();
  Reply held = exchange(encode(sb, RBX1_MSG_MOVE, pb.data(), (uint8_t)pb.size()));
  ASSERT_TRUE(held.got);
  EXPECT_EQ(held.type, RBX1_MSG_NAK);
  EXPECT_EQ(held.payload[0], RBX1_HELD);
  run_ms(5);
  EXPECT_EQ(sim::board().pulses[0], (uint64_t)RBX1_WINDOW * 10);  // not run
  send_run(encode(sa, RBX1_MSG_MOVE, pa.data(), (uint8_t)pa.size()));
  ASSERT_EQ(frames_.size(), 2u);  // the filler's answer, then the held one's
  EXPECT_EQ(frames_[0].seq, sa);
  EXPECT_EQ(frames_[1].seq, sb);
  EXPECT_EQ(frames_[1].type, RBX1_RESPONSE(RBX1_MSG_MOVE));
  EXPECT_EQ(frames_[1].payload[0], RBX1_OK);
  std::vector<uint8_t> held_answer = frames_[1].payload;  // a copy: exchange() clears frames_
  EXPECT_EQ(exchange(encode(sb, RBX1_MSG_MOVE, pb.data(), (uint8_t)pb.size())).payload, held_answer);
  run_until_idle();
  s = status();
  EXPECT_EQ(s.moves_accepted, RBX1_WINDOW + 2);
  EXPECT_EQ(s.position[0], 5);
  EXPECT_EQ(sim::board().pulses[0], (uint64_t)RBX1_WINDOW * 10 + RBX1_WINDOW * 10 + 5);
}

TEST_F(Fw, HeldFramesRunOnceInSeqOrderWhenTheGapIsFilled) {
  ready();
  // Seven MOVEs behind a missing one arrive in reverse order, each twice (a copy of a held one is held once):
  // every one is answered HELD and nothing runs; one further ahead (8) is beyond the window: NAK SEQ_GAP.
  uint8_t first = take_seq();
  std::vector<std::vector<uint8_t>> frames;
  for (int i = 0; i < RBX1_WINDOW; i++) {
    std::vector<uint8_t> p = move_payload({(i + 1) * 10, 0, 0, 0, 0, 0});
    frames.push_back(encode(static_cast<uint8_t>(first + i), RBX1_MSG_MOVE, p.data(), (uint8_t)p.size()));
    if (i) take_seq();
  }
  for (int i = RBX1_WINDOW - 1; i >= 1; i--) {
    for (int copy = 0; copy < 2; copy++) {
      Reply r = exchange(frames[i]);
      ASSERT_TRUE(r.got);
      EXPECT_EQ(r.type, RBX1_MSG_NAK);
      EXPECT_EQ(r.payload[0], RBX1_HELD) << i;
    }
  }
  std::vector<uint8_t> p9 = move_payload({90, 0, 0, 0, 0, 0});
  Reply beyond = exchange(encode(static_cast<uint8_t>(first + RBX1_WINDOW), RBX1_MSG_MOVE, p9.data(), (uint8_t)p9.size()));
  EXPECT_EQ(beyond.payload[0], RBX1_SEQ_GAP);
  run_ms(20);
  EXPECT_EQ(sim::board().pulses[0], 0u);  // nothing held has run
  frames_.clear();
  send_bytes(frames[0].data(), frames[0].size());
  run_ms(10);
  ASSERT_EQ(frames_.size(), (size_t)RBX1_WINDOW);
  for (int i = 0; i < RBX1_WINDOW; i++) {
    EXPECT_EQ(frames_[i].seq, (uint8_t)(first + i));
    EXPECT_EQ(frames_[i].type, RBX1_RESPONSE(RBX1_MSG_MOVE));
    EXPECT_EQ(frames_[i].payload[0], RBX1_OK);
  }
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, RBX1_WINDOW);  // each once
  EXPECT_EQ(s.moves_done, RBX1_WINDOW);
  EXPECT_EQ(s.position[0], RBX1_WINDOW * 10);
  EXPECT_EQ(sim::board().pulses[0], (uint64_t)RBX1_WINDOW * 10);  // in order: 10, 20, ... 80, never backwards
}

TEST_F(Fw, EstopDropsHeldFramesNakedAsGapsAndNeverRuns) {
  ready();
  std::vector<uint8_t> pa = move_payload({100, 0, 0, 0, 0, 0}), pb = move_payload({200, 0, 0, 0, 0, 0});
  uint8_t sa = take_seq(), sb = take_seq();
  std::vector<uint8_t> fb = encode(sb, RBX1_MSG_MOVE, pb.data(), (uint8_t)pb.size());
  EXPECT_EQ(exchange(fb).payload[0], RBX1_HELD);
  // ESTOP: its answer, then NAK SEQ_GAP for the dropped one (not run: the host resends it if it still wants it).
  send_run(encode(sa, RBX1_MSG_ESTOP, nullptr, 0));
  ASSERT_EQ(frames_.size(), 2u);
  EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_ESTOP));
  EXPECT_EQ(frames_[1].type, RBX1_MSG_NAK);
  EXPECT_EQ(frames_[1].seq, sb);
  EXPECT_EQ(frames_[1].payload[0], RBX1_SEQ_GAP);
  // The gap filled after the ESTOP: the missing one runs (refused: the e-stop latched), the dropped one does not.
  send_run(encode(sa, RBX1_MSG_MOVE, pa.data(), (uint8_t)pa.size()));
  ASSERT_EQ(frames_.size(), 1u);
  EXPECT_EQ(frames_[0].seq, sa);
  EXPECT_EQ(frames_[0].payload[0], RBX1_FAULT_ACTIVE);
  Reply again = exchange(fb);  // the dropped one sent again: now in order, run (refused too)
  EXPECT_EQ(again.type, RBX1_RESPONSE(RBX1_MSG_MOVE));
  EXPECT_EQ(again.payload[0], RBX1_FAULT_ACTIVE);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, 0);
  EXPECT_EQ(sim::board().pulses[0], 0u);
}

TEST_F(Fw, HeldStopRunsInItsPlaceInTheOrder) {
  // A STOP held behind a missing MOVE runs after it (its flush removes it) and before the MOVE held behind it.
  ready();
  std::vector<uint8_t> pa = move_payload({4000, 0, 0, 0, 0, 0}), pc = move_payload({300, 0, 0, 0, 0, 0});
  uint8_t sa = take_seq(), sstop = take_seq(), sc = take_seq();
  EXPECT_EQ(exchange(encode(sstop, RBX1_MSG_STOP, nullptr, 0)).payload[0], RBX1_HELD);
  EXPECT_EQ(exchange(encode(sc, RBX1_MSG_MOVE, pc.data(), (uint8_t)pc.size())).payload[0], RBX1_HELD);
  send_run(encode(sa, RBX1_MSG_MOVE, pa.data(), (uint8_t)pa.size()));
  ASSERT_EQ(frames_.size(), 3u);
  EXPECT_EQ(frames_[0].seq, sa);
  EXPECT_EQ(frames_[0].payload[0], RBX1_OK);
  EXPECT_EQ(frames_[1].seq, sstop);
  EXPECT_EQ(frames_[1].type, RBX1_RESPONSE(RBX1_MSG_STOP));
  EXPECT_EQ(frames_[2].seq, sc);
  EXPECT_EQ(frames_[1].payload[0], RBX1_OK);
  EXPECT_EQ(frames_[2].seq, sc);
  // The MOVE after the STOP runs after it, as on a stop-and-wait link: refused BUSY while the arm stops.
  EXPECT_EQ(frames_[2].payload[0], RBX1_BUSY);
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.moves_accepted, 1);
  EXPECT_EQ(s.moves_done + s.moves_flushed, 1);
  EXPECT_EQ(s.position[0], (int32_t)sim::board().pulses[0]);
  EXPECT_LT(s.position[0], 4000);  // stopped short of the first move's target
}

TEST_F(Fw, CorruptFrameIsNakedAndNotExecuted) {
  ready();
  std::vector<uint8_t> p = move_payload({500, 0, 0, 0, 0, 0});
  std::vector<uint8_t> f = encode(7, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());
  f[6] ^= 0x10;  // a payload bit and a CRC bit: two damaged bytes, more than the parity corrects (one)
  f[f.size() - RBX1_FEC_BYTES - 1] ^= 0x01;
  Reply r = exchange(f);
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_MSG_NAK);
  EXPECT_EQ(r.seq, 7);
  ASSERT_EQ(r.payload.size(), 1u);
  EXPECT_EQ(r.payload[0], RBX1_BAD_CRC);
  run_ms(50);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.queue_free, 16);
  EXPECT_EQ(s.moves_done, 0);
  EXPECT_EQ(sim::board().pulses[0], 0u);
}

// Version 5's parity: one damaged byte of a frame, LEN included, is corrected, and the request runs once.
TEST_F(Fw, OneDamagedByteIsCorrectedAndExecutedOnce) {
  ready();
  int32_t target = 0;
  for (size_t at : {size_t(1), size_t(3), size_t(6), size_t(30), size_t(35)}) {  // LEN, TYPE, payload, CRC, parity
    SCOPED_TRACE("byte " + std::to_string(at) + " damaged");
    target += 100;
    std::vector<uint8_t> p = move_payload({target, 0, 0, 0, 0, 0});
    uint8_t seq = take_seq();
    std::vector<uint8_t> f = encode(seq, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());
    ASSERT_LT(at, f.size());
    f[at] ^= 0x24;
    send_run(f);
    ASSERT_EQ(frames_.size(), 1u);
    EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_MOVE));
    EXPECT_EQ(frames_[0].seq, seq);
    EXPECT_EQ(frames_[0].payload[0], RBX1_OK);
    run_until_idle();
    EXPECT_EQ(status().position[0], target);
  }
  EXPECT_EQ(status().moves_accepted, 5);
}

TEST_F(Fw, GarbageIsIgnoredAndAFrameInsideItIsFound) {
  ready();
  std::vector<uint8_t> junk = {0x00, 0x13, 0xFF, 0x42, 0x99, 0x10, 0x20};
  send_run(junk);
  EXPECT_TRUE(frames_.empty()) << "no SYNC, no header: silence";
  // A bad LEN after SYNC is NAKed (BAD_LENGTH), then the real frame behind it is executed.
  std::vector<uint8_t> p = move_payload({0, 300, 0, 0, 0, 0});
  uint8_t seq = take_seq();
  std::vector<uint8_t> f = {RBX1_SYNC, 200, seq};
  std::vector<uint8_t> good = encode(seq, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());
  f.insert(f.end(), good.begin(), good.end());
  send_run(f);
  ASSERT_EQ(frames_.size(), 2u);
  EXPECT_EQ(frames_[0].type, RBX1_MSG_NAK);
  EXPECT_EQ(frames_[0].payload[0], RBX1_BAD_LENGTH);
  EXPECT_EQ(frames_[1].type, RBX1_RESPONSE(RBX1_MSG_MOVE));
  EXPECT_EQ(frames_[1].payload[0], RBX1_OK);
  run_until_idle();
  EXPECT_EQ(status().position[1], 300);
}

TEST_F(Fw, UnknownTypeIsNakedAndWrongLengthAnswered) {
  ready();
  // An unknown type (or a NAK, or a response) is NAKed UNKNOWN_TYPE whatever its SEQ (the next one, a gap, the
  // past) and takes no place in the order: the next request still has the SEQ it used.
  for (uint8_t type : {uint8_t(0x55), uint8_t(RBX1_MSG_NAK), uint8_t(RBX1_RESPONSE(RBX1_MSG_STATUS))})
    for (uint8_t seq : {seq_, uint8_t(seq_ + 3), uint8_t(seq_ - 20)}) {
      Reply r = exchange(encode(seq, type, nullptr, 0));
      ASSERT_TRUE(r.got);
      EXPECT_EQ(r.type, RBX1_MSG_NAK);
      EXPECT_EQ(r.seq, seq);
      EXPECT_EQ(r.payload[0], RBX1_UNKNOWN_TYPE);
    }
  uint8_t status_seq = seq_;
  Reply r = request(RBX1_MSG_STATUS, nullptr, 0);
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_STATUS));
  EXPECT_EQ(r.payload[0], RBX1_OK);
  r = exchange(encode(seq_, 0x55, nullptr, 0));  // HELLO's last_seq names requests, never an unknown type
  uint8_t v = RBX1_PROTO_VERSION;
  r = request(RBX1_MSG_HELLO, &v, 1);
  rbx1_hello_resp h{};
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
  EXPECT_EQ(h.last_seq, status_seq);
  std::vector<uint8_t> p = move_payload({100, 0, 0, 0, 0, 0});
  r = request(RBX1_MSG_MOVE, p.data(), (uint8_t)(p.size() - 1));
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_MOVE));
  EXPECT_EQ(r.payload.size(), (size_t)RBX1_MOVE_RESP_LEN);
  EXPECT_EQ(r.payload[0], RBX1_BAD_LENGTH);
  run_ms(20);
  EXPECT_EQ(status().queue_free, 16);
  EXPECT_EQ(sim::board().pulses[0], 0u);
}

TEST_F(Fw, HelloLastSeqNamesARefusedRequestButNotAnEstop) {
  rbx1_move_req q{};
  uint8_t p[RBX1_MOVE_REQ_LEN];
  Reply r = exchange(encode(77, RBX1_MSG_MOVE, p, rbx1_move_req_pack(&q, p)));  // refused: drivers disabled
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.payload[0], RBX1_DISABLED);
  ASSERT_TRUE(exchange(encode(90, RBX1_MSG_ESTOP, nullptr, 0)).got);  // ESTOPs are not remembered
  uint8_t v = RBX1_PROTO_VERSION;
  r = exchange(encode(78, RBX1_MSG_HELLO, &v, 1));
  rbx1_hello_resp h{};
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
  EXPECT_EQ(h.last_seq, 77);
}

TEST_F(Fw, PartialFrameTimesOut) {
  ready();
  std::vector<uint8_t> p = move_payload({100, 0, 0, 0, 0, 0});
  std::vector<uint8_t> f = encode(3, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());
  frames_.clear();
  send_bytes(f.data(), 10);  // then the line goes quiet for more than 50 ms
  run_ms(80);
  EXPECT_TRUE(frames_.empty());
  Reply r = request(RBX1_MSG_HEARTBEAT, nullptr, 0);  // a fresh frame is understood at once
  ASSERT_TRUE(r.got);
  EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_HEARTBEAT));
}

TEST_F(Fw, FrameSwallowedByAPartialOneIsFoundAfterTheTimeout) {
  ready();
  std::vector<uint8_t> p = move_payload({100, 0, 0, 0, 0, 0});
  std::vector<uint8_t> cut = encode(3, RBX1_MSG_MOVE, p.data(), (uint8_t)p.size());  // never complete: any SEQ
  uint8_t seq = take_seq();
  std::vector<uint8_t> st = encode(seq, RBX1_MSG_STATUS, nullptr, 0);
  frames_.clear();
  send_bytes(cut.data(), 10);  // a MOVE cut short, then a whole STATUS read as its continuation
  send_bytes(st.data(), st.size());
  run_ms(20);
  EXPECT_TRUE(frames_.empty());
  run_ms(60);  // the inter-byte timeout: the MOVE's SYNC is dropped and the STATUS found by the rescan
  ASSERT_EQ(frames_.size(), 1u);
  EXPECT_EQ(frames_[0].type, RBX1_RESPONSE(RBX1_MSG_STATUS));
  EXPECT_EQ(frames_[0].seq, seq);
  EXPECT_EQ(status().moves_accepted, 0);  // the cut MOVE never ran
}

TEST_F(Fw, EstopOfAnyPayloadLengthStopsTheArm) {
  for (uint8_t len : {1, 5, 58}) {
    SCOPED_TRACE("ESTOP with " + std::to_string(len) + " payload bytes");
    ready();
    ASSERT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
    ASSERT_EQ(move({60000, 0, 0, 0, 0, 0}), RBX1_OK);
    run_ms(100);
    std::vector<uint8_t> junk(len, 0x42);
    Reply r = request(RBX1_MSG_ESTOP, junk.data(), len);
    ASSERT_TRUE(r.got);
    EXPECT_EQ(r.type, RBX1_RESPONSE(RBX1_MSG_ESTOP));
    ASSERT_EQ(r.payload.size(), (size_t)RBX1_ESTOP_RESP_LEN);
    EXPECT_EQ(r.payload[0], RBX1_OK);
    uint64_t n = sim::board().pulses[0];
    run_ms(50);
    EXPECT_EQ(sim::board().pulses[0], n) << "pulses after the e-stop";
    rbx1_status_resp s = status();
    EXPECT_EQ(s.state, RBX1_STATE_FAULT);
    EXPECT_TRUE(s.faults & RBX1_FAULT_ESTOP_COMMAND);
    ASSERT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
    ASSERT_EQ(set_position({0, 0, 0, 0, 0, 0}), RBX1_OK);
    sim::board().net[0] = 0;
  }
}

}  // namespace
}  // namespace rbx1::fwtest
