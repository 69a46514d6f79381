// link_test.cpp - Link against a scripted fake firmware on a pty: retransmission, NAK, corruption, duplicates,
// link down, e-stop while a request waits, reconnect after the port vanishes and returns.
#include "link.hpp"

#include <cstdio>
#include <filesystem>
#include <future>
#include <unistd.h>

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include "fake_peer.hpp"
#include "serial_port.hpp"

using namespace std::chrono;
using rbx1::link::Link;
using rbx1::link::test::FakePeer;

namespace {

// RBX1_LOG_DEBUG=1 shows the link's retransmissions and NAKs while a test runs.
const bool debug_logging = [] {
  if (getenv("RBX1_LOG_DEBUG")) spdlog::set_level(spdlog::level::debug);
  return true;
}();

int64_t ms_since(steady_clock::time_point t0) {
  return duration_cast<milliseconds>(steady_clock::now() - t0).count();
}

// All frames after the handshake the peer received with this SEQ (the HELLO's SEQ is random).
std::vector<FakePeer::Received> with_seq(const FakePeer& peer, uint8_t seq) {
  std::vector<FakePeer::Received> out;
  for (const auto& r : peer.received())
    if (r.seq == seq && r.type != RBX1_MSG_HELLO) out.push_back(r);
  return out;
}

rbx1_move_req some_move(int32_t base) {
  rbx1_move_req m{};
  for (int j = 0; j < RBX1_JOINTS; ++j) m.target[j] = base + j;
  m.duration_ms = 250;
  return m;
}

// n moves of targets first, first + 1, ...
std::vector<rbx1_move_req> move_batch(int n, int32_t first) {
  std::vector<rbx1_move_req> v;
  for (int i = 0; i < n; ++i) v.push_back(some_move(first + i));
  return v;
}

// The timeout is 400 ms unless a test is about the timeout itself, so a loaded machine (2 cores shared by
// parallel builds and tests) cannot add retransmissions the test did not cause.
struct LinkTest : ::testing::Test {
  FakePeer peer;
  Link link;
  rbx1::link::LinkStats base;
  void SetUp() override {
    std::string error;
    link.set_timing(400, 5);
    ASSERT_EQ(link.open(peer.slave_path(), 115200, error), 0) << error;
    base = link.stats();
  }
  // Streams n moves (move_batch) and checks that every one was answered (and OK).
  void stream_all_ok(int n, int32_t first) {
    std::vector<rbx1_move_resp> out;
    std::vector<bool> answered;
    ASSERT_EQ(link.move_stream(move_batch(n, first), out, answered), 0);
    for (int i = 0; i < n; ++i) {
      EXPECT_TRUE(answered[i]) << i;
      EXPECT_EQ(out[i].status, RBX1_OK) << i;
    }
  }
  // Counters since SetUp (the handshake excluded).
  rbx1::link::LinkStats delta() const {
    rbx1::link::LinkStats s = link.stats();
    s.requests -= base.requests;
    s.retransmissions -= base.retransmissions;
    s.timeouts -= base.timeouts;
    s.naks -= base.naks;
    s.stale -= base.stale;
    s.rejected -= base.rejected;
    s.link_down -= base.link_down;
    s.probes -= base.probes;
    return s;
  }
};

}  // namespace

TEST_F(LinkTest, HelloStartsASessionAndNumberingFollowsIt) {
  EXPECT_EQ(link.firmware().joints, 6);
  EXPECT_EQ(link.firmware().fw_minor, 9);
  EXPECT_EQ(link.firmware().window, RBX1_WINDOW);
  EXPECT_EQ(link.window(), RBX1_WINDOW);
  const uint8_t hello_seq = peer.received().back().seq;
  EXPECT_EQ(link.next_seq(), static_cast<uint8_t>(hello_seq + 1));  // whatever the peer's last_seq (41)
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(s.status, RBX1_OK);
  EXPECT_EQ(s.position[5], 2500);
  EXPECT_EQ(peer.received().back().seq, static_cast<uint8_t>(hello_seq + 1));
  EXPECT_EQ(delta().retransmissions, 0u);
  EXPECT_EQ(peer.refused(), 0);
  link.set_window(3);
  EXPECT_EQ(link.window(), 3);
}

TEST_F(LinkTest, EveryTypedHelperGetsItsResponse) {
  rbx1_move_resp mv{};
  ASSERT_EQ(link.move(some_move(100), mv), 0);
  EXPECT_EQ(mv.queue_free, 7);
  rbx1_gripper_resp gr{};
  ASSERT_EQ(link.gripper({1500, 100}, gr), 0);
  rbx1_config_get_resp cg{};
  ASSERT_EQ(link.config_get(3, RBX1_KEY_ACCEL, cg), 0);
  EXPECT_EQ(cg.value, 304);
  rbx1_heartbeat_resp hb{};
  rbx1_home_resp ho{};
  rbx1_stop_resp st{};
  rbx1_clear_fault_resp cf{};
  rbx1_enable_resp en{};
  rbx1_set_position_resp sp{};
  rbx1_config_set_resp cs{};
  rbx1_config_reset_resp cr{};
  int32_t pos[RBX1_JOINTS] = {1, 2, 3, 4, 5, 6};
  EXPECT_EQ(link.heartbeat(hb), 0);
  EXPECT_EQ(link.home(0, ho), 0);
  EXPECT_EQ(link.stop(st), 0);
  EXPECT_EQ(link.clear_fault(cf), 0);
  EXPECT_EQ(link.enable(true, en), 0);
  EXPECT_EQ(link.set_position(pos, sp), 0);
  EXPECT_EQ(link.config_set(RBX1_GLOBAL_JOINT, RBX1_KEY_HEARTBEAT_MS, 500, cs), 0);
  EXPECT_EQ(link.config_reset(cr), 0);
  EXPECT_EQ(link.estop(), 0);
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(s.moves_done, 2);
  for (uint8_t t = RBX1_MSG_HELLO; t <= RBX1_MSG_CONFIG_RESET; ++t) EXPECT_GE(peer.executed(t), 1) << int(t);
  EXPECT_EQ(delta().requests, 13u);
}

TEST_F(LinkTest, RetransmitsTheSameBytesOnSilence) {
  peer.drop_next = 2;
  uint8_t seq = link.next_seq();
  auto t0 = steady_clock::now();
  rbx1_move_resp r{};
  ASSERT_EQ(link.move(some_move(5), r), 0);
  int64_t took = ms_since(t0);
  EXPECT_GE(took, 790);  // two 400 ms timeouts (the counts below say no third one; wall time on a loaded machine
                         // says nothing more)
  auto frames = with_seq(peer, seq);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].crc, frames[1].crc);
  EXPECT_EQ(frames[0].crc, frames[2].crc);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  EXPECT_EQ(delta().retransmissions, 2u);
  EXPECT_EQ(delta().timeouts, 2u);
}

TEST_F(LinkTest, RetransmitsAtOnceOnNak) {
  link.set_timing(20000, 5);  // a timeout waited would show as 20 s, which no load on the machine comes near
  peer.nak_next = 3;
  uint8_t seq = link.next_seq();
  auto t0 = steady_clock::now();
  rbx1_move_resp r{};
  ASSERT_EQ(link.move(some_move(7), r), 0);
  EXPECT_LT(ms_since(t0), 20000);  // no timeout waited (and none counted below)
  EXPECT_EQ(with_seq(peer, seq).size(), 4u);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  EXPECT_EQ(delta().naks, 3u);
  EXPECT_EQ(delta().retransmissions, 3u);
  EXPECT_EQ(delta().timeouts, 0u);
}

TEST_F(LinkTest, UnknownTypeIsNotRetransmittedAndTakesNoSeq) {
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine (a stream: 1 s past due)
  uint8_t resp[RBX1_MAX_PAYLOAD];
  uint8_t len = 0;
  uint8_t seq = link.next_seq();
  EXPECT_EQ(link.request(0x33, nullptr, 0, resp, len), -EOPNOTSUPP);
  EXPECT_EQ(delta().naks, 1u);
  EXPECT_EQ(delta().retransmissions, 0u);
  EXPECT_EQ(delta().link_down, 0u);
  // An unknown type has no place in the firmware's order: its SEQ is the next request's, which runs at once (a
  // skipped SEQ would be a gap).
  EXPECT_EQ(link.next_seq(), seq);
  rbx1_status_resp s{};
  EXPECT_EQ(link.status(s), 0);  // the link is fine
  EXPECT_EQ(delta().retransmissions, 0u);
  auto rx = with_seq(peer, seq);
  ASSERT_EQ(rx.size(), 2u);
  EXPECT_EQ(rx[0].type, 0x33);
  EXPECT_EQ(rx[1].type, RBX1_MSG_STATUS);
  EXPECT_EQ(peer.refused(), 0);
}

TEST_F(LinkTest, NakUnknownTypeOfARequestTypeIsAPlainNak) {
  // A NAK UNKNOWN_TYPE naming a request type's SEQ (a damaged or stale frame: nothing ran) is sent again.
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine (a stream: 1 s past due)
  peer.nak_reason = RBX1_UNKNOWN_TYPE;
  peer.nak_next = 2;
  rbx1_move_resp r{};
  ASSERT_EQ(link.move(some_move(7), r), 0);
  EXPECT_EQ(r.status, RBX1_OK);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  EXPECT_EQ(delta().retransmissions, 2u);
  peer.nak_next = 2;
  std::vector<rbx1_move_req> batch;
  for (int i = 0; i < 10; ++i) batch.push_back(some_move(100 + i));
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  ASSERT_EQ(link.move_stream(batch, out, answered), 0);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(out[i].status, RBX1_OK) << i;
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 11);  // each once
}

TEST_F(LinkTest, CorruptResponseIsRetransmittedNotReExecuted) {
  peer.corrupt_next = 1;
  rbx1_move_resp r{};
  ASSERT_EQ(link.move(some_move(9), r), 0);
  EXPECT_EQ(r.queue_free, 7);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  // One retransmission, or more when a loaded machine (TSan) holds the peer's answer past the 400 ms: every one of
  // them is answered from the cache, none runs again.
  EXPECT_GE(delta().retransmissions, 1u);
  EXPECT_EQ(size_t(peer.cached_replies()), size_t(delta().retransmissions));
  EXPECT_GE(delta().rejected, 1u);
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(s.moves_done, 1);
}

TEST_F(LinkTest, StreamKeepsTheWindowInFlight) {
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine (a stream: 1 s past due)
  stream_all_ok(40, 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 40);
  EXPECT_EQ(peer.cached_replies(), 0);
  EXPECT_EQ(peer.refused(), 0);
  EXPECT_EQ(delta().retransmissions, 0u);
  // SEQs of the requests on the wire: consecutive, each once; then the one probe behind the last request (PROTOCOL.md
  // "Probe": a frame of TYPE 0x7F with the SEQ before the oldest unanswered request), answered UNKNOWN_TYPE.
  // The stream ends with the last answer: the peer's thread may read the probe behind it a little later.
  EXPECT_EQ(delta().probes, 1u);
  auto rx = peer.received();
  for (auto t0 = steady_clock::now(); (rx.empty() || rx.back().type != RBX1_MSG_NAK) && ms_since(t0) < 10000;
       rx = peer.received())
    std::this_thread::sleep_for(milliseconds(1));
  ASSERT_GE(rx.size(), 41u);
  EXPECT_EQ(rx.back().type, RBX1_MSG_NAK);
  rx.pop_back();
  EXPECT_EQ(rx.back().type, RBX1_MSG_MOVE);
  for (size_t i = rx.size() - 39; i < rx.size(); ++i) EXPECT_EQ(rx[i].seq, static_cast<uint8_t>(rx[i - 1].seq + 1));
}

TEST_F(LinkTest, StreamHoldsTheFramesAfterALostRequest) {
  link.set_timing(4000, 5);  // no timeout (it would send the held ones again), however loaded the machine
  link.set_ahead(0);         // the whole window written at once (no pacing): the 7 after the lost one are held
  peer.drop_next = 1;  // the stream's first frame vanishes: the peer holds the ones after it until it comes again
  stream_all_ok(20, 0);
  std::vector<int32_t> in_order(20);
  for (int i = 0; i < 20; ++i) in_order[i] = i;
  EXPECT_EQ(peer.move_targets(), in_order);  // nothing lost, nothing twice, in order
  EXPECT_EQ(peer.held(), 7);                 // NAK HELD for the 7 frames after the lost one
  EXPECT_EQ(peer.refused(), 0);
  EXPECT_GE(delta().retransmissions, 1u);
}

TEST_F(LinkTest, StreamHeldAnswersLostAreSentAgain) {
  // The first frame vanishes, its 7 followers are held; when the gap is filled they all run and answer at once.
  // The filler's answer arrives broken: the held ones' answers show it ran (SEQ order), so it is sent again and
  // answered from memory, with no timeout.
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine (a stream: 1 s past due)
  const int cached0 = peer.cached_replies();  // a HELLO sent again in SetUp (a loaded machine) is answered too
  peer.drop_next = 1;
  peer.corrupt_next = 1;  // HELD NAKs do not use it: the filler's answer is the next response
  stream_all_ok(10, 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 10);
  EXPECT_EQ(peer.cached_replies() - cached0, 1);
  EXPECT_LE(delta().retransmissions, 2u);  // the lost request, then its lost answer: once, whatever the reads
  EXPECT_EQ(delta().timeouts, 0u);
}

TEST_F(LinkTest, StreamLostAnswersComeFromTheWindow) {
  peer.corrupt_next = 2;  // the first two answers arrive broken: those requests are sent again, answered from memory
  stream_all_ok(12, 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 12);
  EXPECT_GE(peer.cached_replies(), 2);
}

TEST_F(LinkTest, StreamResendsOnlyWhatTheAnswersShowLost) {
  // Answers and NAKs come back in the order of the copies written: a lost answer costs one resend of its request,
  // a lost request one resend of it alone (its followers are held: NAK HELD), nothing more (a timeout would resend
  // all).
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine (a stream: 1 s past due)
  peer.corrupt_next = 1;  // the first answer arrives broken
  stream_all_ok(12, 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 12);
  EXPECT_EQ(delta().retransmissions, 1u);
  EXPECT_EQ(delta().timeouts, 0u);
  peer.drop_next = 1;  // the next stream's first frame vanishes: its 7 followers in the window are held
  link.set_ahead(0);   // (the whole window written at once, no pacing)
  stream_all_ok(12, 100);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 24);
  EXPECT_EQ(peer.held(), 7);
  EXPECT_EQ(peer.refused(), 0);
  EXPECT_EQ(delta().retransmissions, 1u + 1u);  // delta(): since the test began
  EXPECT_EQ(delta().timeouts, 0u);
}

TEST_F(LinkTest, StreamLostResendIsSentAgainAfterTheProbeNotTheTimeout) {
  // The first request vanishes and so does its first resend (written when its followers came back held): the
  // probe written behind that resend is answered after it, which shows it lost, and it goes again at once. Without
  // the probe only the timeout (2 s here) would send it again: the count of timeouts tells.
  link.set_timing(4000, 5);  // a stream's deadline: a quarter of it (1 s) after the answer is due
  link.set_ahead(0);  // the whole window at once: nothing new can follow the resend, only the probe
  const int cached0 = peer.cached_replies();  // a HELLO sent again in SetUp (a loaded machine) is answered too
  peer.drop_seq = link.next_seq();
  peer.drop_seq_times = 2;
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  ASSERT_EQ(link.move_stream(move_batch(10, 0), out, answered), 0);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(out[i].status, RBX1_OK) << i;
  std::vector<int32_t> in_order(10);
  for (int i = 0; i < 10; ++i) in_order[i] = i;
  EXPECT_EQ(peer.move_targets(), in_order);  // nothing lost, nothing twice, in order
  EXPECT_EQ(peer.cached_replies(), cached0);
  EXPECT_EQ(delta().timeouts, 0u);
  EXPECT_EQ(delta().retransmissions, 2u);  // the first request's two resends, nothing else
  EXPECT_GE(delta().probes, 2u);           // behind each resend (and behind the stream's last request)
}

TEST_F(LinkTest, StreamPacedHoldsFewerFollowersOfALostRequest) {
  // Paced (PROTOCOL.md "Pacing"): no more than kAhead copies on the line beyond the latest one an answer or NAK was
  // about, so a lost request has kAhead - 1 followers held when its resend goes out, not the window's 7.
  link.set_timing(4000, 5);  // no timeout in this test, however loaded the machine
  peer.drop_next = 1;
  stream_all_ok(20, 0);
  std::vector<int32_t> in_order(20);
  for (int i = 0; i < 20; ++i) in_order[i] = i;
  EXPECT_EQ(peer.move_targets(), in_order);  // nothing lost, nothing twice, in order
  EXPECT_EQ(peer.held(), rbx1::link::Link::kAhead - 1);
  EXPECT_EQ(peer.refused(), 0);
  EXPECT_EQ(delta().retransmissions, 1u);
  EXPECT_EQ(delta().timeouts, 0u);
}

TEST_F(LinkTest, StreamPacedGoesOnWhenLateCopiesAnswersAreStale) {
  // Every answer comes late, after the timeout's resend: the late answer is taken and the resend's answer (from
  // memory) is stale. Nothing is in flight then, so what was left on the line must not hold back the rest: before
  // this rule the stream spun forever with every request written answered and no room to write more.
  link.set_timing(400, 5);  // a stream's deadline: 100 ms after the answer is due, doubled by each silence
  link.set_ahead(1);
  peer.delay_all_ms = 150;  // answers and NAKs late, in order
  auto done = std::async(std::launch::async, [&] {
    std::vector<rbx1_move_resp> out;
    std::vector<bool> answered;
    return link.move_stream(move_batch(3, 0), out, answered);
  });
  if (done.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
    ADD_FAILURE() << "the stream stopped writing with nothing in flight";
    std::_Exit(1);  // the stream's thread spins on: nothing else can end this test
  }
  EXPECT_EQ(done.get(), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 3);
  EXPECT_GE(delta().timeouts, 1u);
}

TEST_F(LinkTest, StreamPacedLostResendIsShownByTheRequestsAfterIt) {
  // Paced, new requests follow a resend: their NAKs (HELD) come after it, so a lost resend is sent again at once,
  // with neither a probe behind it nor a timeout.
  link.set_timing(4000, 5);
  peer.drop_seq = link.next_seq();
  peer.drop_seq_times = 2;
  stream_all_ok(20, 0);
  std::vector<int32_t> in_order(20);
  for (int i = 0; i < 20; ++i) in_order[i] = i;
  EXPECT_EQ(peer.move_targets(), in_order);
  EXPECT_EQ(delta().timeouts, 0u);
  EXPECT_EQ(delta().retransmissions, 2u);
  EXPECT_EQ(delta().probes, 1u);  // only behind the stream's last request
}

TEST_F(LinkTest, StreamLostLastRequestIsSentAgainAfterTheProbe) {
  // Nothing follows the stream's last request but the probe: its NAK shows the request lost, without a timeout.
  link.set_timing(4000, 5);  // a stream's deadline: a quarter of it (1 s) after the answer is due
  const int cached0 = peer.cached_replies();
  peer.drop_seq = static_cast<uint8_t>(link.next_seq() + 9);
  peer.drop_seq_times = 1;
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  ASSERT_EQ(link.move_stream(move_batch(10, 0), out, answered), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 10);
  EXPECT_EQ(peer.cached_replies(), cached0);
  EXPECT_EQ(delta().timeouts, 0u);
  EXPECT_EQ(delta().retransmissions, 1u);
}

TEST_F(LinkTest, StreamSilenceTimesOutOnTheLineModelBeforeTheTimeout) {
  // The stream's only request and the probe behind it vanish: nothing shows the loss but silence. The deadline is
  // the answer's due time on the line model plus a quarter of the timeout (PROTOCOL.md "Timeout"): the request goes
  // again about 1 s after the first copy, not after the 4 s of the timeout.
  link.set_timing(4000, 5);
  peer.drop_seq = link.next_seq();
  peer.drop_seq_times = 1;
  peer.drop_probes = 1;
  const size_t rx0 = peer.received().size();
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  ASSERT_EQ(link.move_stream(move_batch(1, 0), out, answered), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  EXPECT_EQ(delta().timeouts, 1u);
  EXPECT_EQ(delta().retransmissions, 1u);
  auto rx = peer.received();
  ASSERT_GE(rx.size(), rx0 + 3);  // the request, its probe, the request again
  EXPECT_EQ(rx[rx0 + 2].crc, rx[rx0].crc);
  const auto gap = std::chrono::duration_cast<std::chrono::milliseconds>(rx[rx0 + 2].at - rx[rx0].at).count();
  EXPECT_GE(gap, 500);   // not before its deadline (1 s past due; 500: the first copy may have been read late)
  EXPECT_LT(gap, 3000);  // the fixed timeout could not resend it before 4000
}

TEST_F(LinkTest, StreamStopAndWaitWritesNoProbe) {
  link.set_window(1);
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  ASSERT_EQ(link.move_stream(move_batch(5, 0), out, answered), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 5);
  EXPECT_EQ(delta().probes, 0u);
  EXPECT_EQ(peer.unknown(), 0);
}

TEST_F(LinkTest, StreamLinkDownSaysWhichWereAnswered) {
  // Down after 3 silences (125, 250 and 500 ms past the answers' due times on the line model, PROTOCOL.md
  // "Timeout"): the peer's three answers come well before that.
  link.set_timing(500, 2);
  link.set_ahead(0);  // the whole window written at once: the count of frames written below
  peer.silence_after_type = RBX1_MSG_MOVE;  // three MOVEs run and are answered, then the line dies
  peer.silence_after_count = 2;
  std::vector<rbx1_move_resp> out;
  std::vector<bool> answered;
  const size_t rx0 = peer.received().size();
  EXPECT_EQ(link.move_stream(move_batch(10, 0), out, answered), -ETIMEDOUT);
  // The silence ends only after the peer has read every copy the link wrote (10 frames, the resends and the probes
  // behind them): a copy read after it would run (a loaded machine can hold the peer's thread back that long).
  const size_t written = 10 + delta().retransmissions + delta().probes;
  for (auto t0 = steady_clock::now(); peer.received().size() < rx0 + written && ms_since(t0) < 10000;)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_EQ(peer.received().size(), rx0 + written);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 3);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(answered[i], i < 3) << i;
  peer.silence_after_type = -1;
  // The fixture's patience again for the new session: at 250 ms x 2 a peer thread held up by a loaded machine
  // once left the HELLO unanswered (1 run in 60 at load 11).
  link.set_timing(1000, 5);
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);  // a HELLO first (the new session), then the STATUS
  EXPECT_EQ(s.moves_done, 3);
  EXPECT_EQ(peer.refused(), 0);
}

TEST_F(LinkTest, DuplicateAndStaleResponsesAreDiscarded) {
  peer.duplicate = true;
  peer.stale_first = true;
  rbx1_move_resp r{};
  for (int i = 0; i < 3; ++i) ASSERT_EQ(link.move(some_move(i * 10), r), 0);
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(s.status, RBX1_OK);
  EXPECT_EQ(s.moves_done, 3);  // the STATUS answer, not a late MOVE duplicate
  std::this_thread::sleep_for(milliseconds(30));
  // 4 requests: each had one stale response before and one duplicate after. Setting peer.duplicate races with
  // the peer thread still finishing the handshake, so a duplicate HELLO answer may arrive too: at most one more.
  EXPECT_GE(delta().stale, 8u);
  EXPECT_LE(delta().stale, 9u);
  EXPECT_EQ(delta().retransmissions, 0u);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 3);
}

TEST_F(LinkTest, LinkDownAfterFiveRetransmissions) {
  link.set_timing(100, 5);  // PROTOCOL.md's numbers
  peer.drop_next = 1000;
  uint8_t seq = link.next_seq();
  auto t0 = steady_clock::now();
  rbx1_status_resp s{};
  EXPECT_EQ(link.status(s), -ETIMEDOUT);
  int64_t took = ms_since(t0);
  EXPECT_GE(took, 590);  // six 100 ms timeouts; the frame count below says there were no more
  // The last copy went out 100 ms before the link gave up: a peer thread held up by a loaded machine may read it
  // later still.
  for (auto t1 = steady_clock::now(); with_seq(peer, seq).size() < 6u && ms_since(t1) < 10000;)
    std::this_thread::sleep_for(milliseconds(1));
  EXPECT_EQ(with_seq(peer, seq).size(), 6u);
  EXPECT_EQ(delta().retransmissions, 5u);
  EXPECT_EQ(delta().link_down, 1u);
  // The link recovers when the peer answers again: a HELLO first (the lost SEQ would be a gap in the firmware's
  // order), then the request, each with a new SEQ (with the fixture's patience: this is not about the timing).
  peer.drop_next = 0;
  link.set_timing(1000, 5);
  ASSERT_EQ(link.status(s), 0);
  auto rx = peer.received();
  ASSERT_GE(rx.size(), 2u);
  EXPECT_EQ(rx[rx.size() - 2].type, RBX1_MSG_HELLO);
  EXPECT_EQ(rx[rx.size() - 2].seq, static_cast<uint8_t>(seq + 1));
  EXPECT_EQ(rx.back().seq, static_cast<uint8_t>(seq + 2));
  EXPECT_EQ(peer.refused(), 0);
}

TEST_F(LinkTest, ConfiguredTimingIsUsed) {
  // Longer than the default timeout and fewer tries: only lower bounds and counts, which a loaded machine cannot
  // break (an upper bound on 3 x 30 ms failed at 681 ms at load 20).
  link.set_timing(250, 1);
  peer.drop_next = 1000;
  uint8_t seq = link.next_seq();
  auto t0 = steady_clock::now();
  rbx1_status_resp s{};
  EXPECT_EQ(link.status(s), -ETIMEDOUT);
  EXPECT_GE(ms_since(t0), 490);  // 2 x 250 ms; the default 100 ms would give 2 x 100
  EXPECT_EQ(with_seq(peer, seq).size(), 2u);  // the default would send it 6 times
  EXPECT_EQ(delta().retransmissions, 1u);
}

TEST_F(LinkTest, EstopGoesOutWhileARequestWaits) {
  link.set_timing(1000, 5);  // the held MOVE response must not be retransmitted, even on a loaded machine
  peer.delay_type = RBX1_MSG_MOVE;
  peer.delay_ms = 300;
  auto move = std::async(std::launch::async, [&] {
    rbx1_move_resp r{};
    return link.move(some_move(1), r);
  });
  std::this_thread::sleep_for(milliseconds(30));  // the MOVE is on the wire, its response held
  rbx1_estop_resp e{};
  ASSERT_EQ(link.estop(e), 0);
  EXPECT_EQ(e.status, RBX1_OK);
  // No wall-clock bound (one failed under TSan): the ESTOP answered before the delayed MOVE is the check below.
  EXPECT_EQ(move.wait_for(milliseconds(0)), std::future_status::timeout);  // still outstanding
  EXPECT_EQ(move.get(), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_ESTOP), 1);
  EXPECT_EQ(peer.executed(RBX1_MSG_MOVE), 1);
  EXPECT_LT(peer.sent_at(RBX1_MSG_ESTOP), peer.sent_at(RBX1_MSG_MOVE));
  EXPECT_EQ(delta().retransmissions, 0u);
}

TEST_F(LinkTest, EstopFromManyThreads) {
  std::vector<std::future<int>> f;
  for (int i = 0; i < 4; ++i) f.push_back(std::async(std::launch::async, [&] { return link.estop(); }));
  rbx1_status_resp s{};
  EXPECT_EQ(link.status(s), 0);
  for (auto& x : f) EXPECT_EQ(x.get(), 0);
  EXPECT_EQ(peer.executed(RBX1_MSG_ESTOP), 4);
}

TEST_F(LinkTest, HeartbeatOnlyWhenIdle) {
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(link.heartbeat_if_due(5000), 0);  // a request just completed: not due
  EXPECT_EQ(peer.executed(RBX1_MSG_HEARTBEAT), 0);
  std::this_thread::sleep_for(milliseconds(60));
  EXPECT_EQ(link.heartbeat_if_due(50), 0);  // idle longer than 50 ms: sent
  EXPECT_EQ(peer.executed(RBX1_MSG_HEARTBEAT), 1);
  EXPECT_EQ(link.heartbeat_if_due(5000), 0);  // and that one fed it again
  EXPECT_EQ(peer.executed(RBX1_MSG_HEARTBEAT), 1);
  // The background thread: never more often than the period, and silent once stopped.
  auto t0 = steady_clock::now();
  link.start_heartbeat(50);
  while (peer.executed(RBX1_MSG_HEARTBEAT) < 4 && ms_since(t0) < 3000) std::this_thread::sleep_for(milliseconds(2));
  link.stop_heartbeat();
  int n = peer.executed(RBX1_MSG_HEARTBEAT);
  EXPECT_GE(n, 4);
  EXPECT_GE(ms_since(t0), 140);  // three more at >= 50 ms spacing
  std::this_thread::sleep_for(milliseconds(120));
  EXPECT_EQ(peer.executed(RBX1_MSG_HEARTBEAT), n);
}

// The device vanishes while a request waits for its answer: the caller hears at once, not after 6 timeouts.
TEST(Link, VanishingDeviceEndsAnOutstandingRequest) {
  auto peer = std::make_unique<FakePeer>();
  Link link;
  link.set_timing(20000, 5);  // one timeout waited would show as 20 s, which no load on the machine comes near
  std::string error;
  ASSERT_EQ(link.open(peer->slave_path(), 115200, error), 0) << error;
  peer->drop_next = 1000;
  auto t0 = steady_clock::now();  // before the thread starts its 150 ms: taken after, a late main thread saw 131 ms
  std::thread unplug([&] {
    std::this_thread::sleep_for(milliseconds(150));
    peer->hang_up();
  });
  rbx1_move_resp r{};
  int rc = link.move(some_move(1), r);
  int64_t took = ms_since(t0);
  unplug.join();
  EXPECT_TRUE(rc == -ENODEV || rc == -EIO) << rc;
  EXPECT_GE(took, 140);
  EXPECT_LT(took, 20000);  // not even the first of the 6 x 20 s of retransmissions was waited out
  EXPECT_FALSE(link.connected());
  EXPECT_EQ(link.stats().link_down, 0u);
  EXPECT_EQ(link.estop(), rc);  // every call now says the port is gone
}

// Any fd (here the pty opened by the test itself): no termios changes by the Link, and no reopening.
TEST(Link, OpenFdSpeaksOverAnyDescriptor) {
  FakePeer peer;
  std::string error;
  int fd = rbx1::link::open_serial(peer.slave_path(), 115200, error);
  ASSERT_GE(fd, 0) << error;
  Link link;
  ASSERT_EQ(link.open_fd(fd, "fake-fd", error), 0) << error;
  EXPECT_EQ(link.name(), "fake-fd");
  rbx1_config_get_resp g{};
  ASSERT_EQ(link.config_get(RBX1_GLOBAL_JOINT, RBX1_KEY_HEARTBEAT_MS, g), 0);
  EXPECT_EQ(g.value, 255 * 100 + 16);
  EXPECT_EQ(link.reconnect(error), -EOPNOTSUPP);
  EXPECT_EQ(error, "fake-fd: opened from an fd, cannot be reopened");
}

// A board that answers only after its bootloader ran (the first open after plug-in resets an Arduino).
TEST(Link, HandshakeWaitsForABootingBoard) {
  FakePeer peer;
  peer.drop_next = 9;  // 1.5 HELLO exchanges of silence
  Link link;
  link.set_boot_wait(1500);  // HELLO (0.6 s unanswered), quiet for the rest, HELLO again
  std::string error;
  ASSERT_EQ(link.open(peer.slave_path(), 115200, error), 0) << error;
  EXPECT_EQ(peer.executed(RBX1_MSG_HELLO), 1);
  EXPECT_GE(link.stats().link_down, 1u);  // the first HELLO exchange went unanswered
}

TEST(Link, VersionMismatchIsAClearError) {
  FakePeer peer;
  peer.proto_version = RBX1_PROTO_VERSION + 1;
  Link link;
  std::string error;
  EXPECT_EQ(link.open(peer.slave_path(), 115200, error), -EPROTO);
  EXPECT_NE(error.find("protocol version " + std::to_string(RBX1_PROTO_VERSION + 1) + ", this host " +
                       std::to_string(RBX1_PROTO_VERSION)),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("rbx1-flash " + peer.slave_path()), std::string::npos) << error;
  EXPECT_NE(error.find("make flash PORT=" + peer.slave_path() + ")"), std::string::npos) << error;
  EXPECT_FALSE(link.connected());
}

// A board still on protocol version 4 reads our frames (its CRC holds where it looks; it hunts past the parity) and
// answers HELLO BAD_VERSION, version 4, in frames without parity: read at their CRC, the error names both versions
// and the fix.
TEST(Link, Version4FirmwareIsAClearError) {
  FakePeer peer;
  peer.proto_version = 4;
  peer.v4_frames = true;
  Link link;
  std::string error;
  EXPECT_EQ(link.open(peer.slave_path(), 115200, error), -EPROTO);
  const std::string& port = peer.slave_path();
  EXPECT_EQ(error, port + ": firmware speaks protocol version 4, this host " + std::to_string(RBX1_PROTO_VERSION) +
                       "; flash the matching firmware: rbx1-flash " + port + " (from a checkout: make flash PORT=" +
                       port + ")");
  EXPECT_EQ(peer.executed(RBX1_MSG_HELLO), 1);  // answered at once: no HELLO repeated, no bootloader wait
  EXPECT_FALSE(link.connected());
}

TEST(Link, MissingPortNamesThePath) {
  Link link;
  std::string error;
  EXPECT_EQ(link.open("/nonexistent/ttyRBX1", 115200, error), -ENOENT);
  EXPECT_EQ(error.rfind("/nonexistent/ttyRBX1: ", 0), 0u) << error;
  rbx1_status_resp s{};
  EXPECT_EQ(link.status(s), -ENOTCONN);
  EXPECT_EQ(link.estop(), -ENOTCONN);
}

TEST(Link, SilentPeerFailsTheHandshake) {
  FakePeer peer;
  peer.drop_next = 1000;
  Link link;
  link.set_timing(20, 1);
  link.set_boot_wait(300);
  std::string error;
  auto t0 = steady_clock::now();
  EXPECT_EQ(link.open(peer.slave_path(), 115200, error), -ETIMEDOUT);
  EXPECT_GE(ms_since(t0), 300);  // HELLO, quiet through the boot wait, HELLO again
  EXPECT_LT(ms_since(t0), 1500);
  EXPECT_NE(error.find("no HELLO response"), std::string::npos) << error;
  // HELLO exchanges of 2 transmissions, silence between them (the peer's thread may read the last ones later).
  for (auto t1 = steady_clock::now(); peer.received().size() < 4u && ms_since(t1) < 10000;)
    std::this_thread::sleep_for(milliseconds(1));
  EXPECT_GE(peer.received().size(), 4u);
  EXPECT_EQ(peer.executed(RBX1_MSG_HELLO), 0);
}

// The port is a symlink (as a udev rule makes one); the device behind it vanishes and a new one appears.
TEST(Link, ReconnectsWhenThePortReturns) {
  auto dir = std::filesystem::temp_directory_path() / ("rbx1-link-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  auto port = dir / "ttyRBX1";
  std::filesystem::remove(port);
  auto a = std::make_unique<FakePeer>();
  std::filesystem::create_symlink(a->slave_path(), port);
  Link link;
  link.set_timing(1000, 5);  // a loaded machine must not turn one HELLO into two (the SEQ checks below)
  std::string error;
  ASSERT_EQ(link.open(port, 250000, error), 0) << error;
  rbx1_move_resp mr{};
  ASSERT_EQ(link.move(some_move(3), mr), 0);

  FakePeer b;  // made first, so it cannot reuse the vanished device's /dev/pts number
  b.last_seq = 200;
  // The USB device vanishes, and udev removes its symlink (a stale path could lead to an unrelated pty).
  std::filesystem::remove(port);
  a->hang_up();
  auto t0 = steady_clock::now();
  while (link.connected() && ms_since(t0) < 1000) std::this_thread::sleep_for(milliseconds(5));
  EXPECT_FALSE(link.connected());
  EXPECT_LT(ms_since(t0), 500);  // seen without a request outstanding
  rbx1_status_resp s{};
  int r = link.status(s);
  EXPECT_TRUE(r == -ENODEV || r == -EIO) << r;
  EXPECT_EQ(link.reconnect(error), -ENOENT);
  EXPECT_EQ(error.rfind(port.string() + ": ", 0), 0u) << error;

  t0 = steady_clock::now();
  std::thread swap([&] {
    std::this_thread::sleep_for(milliseconds(150));
    auto tmp = dir / "new";
    std::filesystem::create_symlink(b.slave_path(), tmp);
    std::filesystem::rename(tmp, port);
  });
  EXPECT_EQ(link.wait_reconnect(2000, error), 0) << error;
  EXPECT_GE(ms_since(t0), 140);  // only once the path leads to a device again
  swap.join();
  const uint8_t hello_seq = b.received().back().seq;  // a new session: numbering follows the HELLO
  EXPECT_EQ(b.received().back().type, RBX1_MSG_HELLO);
  EXPECT_EQ(link.next_seq(), static_cast<uint8_t>(hello_seq + 1));
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(b.received().back().seq, static_cast<uint8_t>(hello_seq + 1));
  EXPECT_EQ(b.executed(RBX1_MSG_HELLO), 1);
  EXPECT_EQ(link.stats().reconnects, 1u);
  link.close();
  std::filesystem::remove_all(dir);
}
