// window_sender.hpp - the window sender of Link::stream (PROTOCOL.md "Window", "Probe", "Pacing", "Timeout") as
// state and steps without I/O: told the frames received and the time, it says what to write. The Python sender
// (protocol/python/rbx1proto/sender.py) reproduces the same traces (protocol/vectors/sender_traces.json).
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <utility>
#include <vector>

#include "rbx1_proto.h"

namespace rbx1::link {

// One write: the frames of these requests (indices, oldest first), then a probe with SEQ probe_seq when probe.
struct SenderWrite {
  std::vector<size_t> frames;
  bool probe = false;
  uint8_t probe_seq = 0;
};

struct SenderSettings {
  size_t window = 1;   // requests in flight at most
  uint32_t ahead = 4;  // copies on the line beyond the latest one an answer or NAK was about (PROTOCOL.md "Pacing"; 0: none)
  int timeout_ms = 100;
  int baud = 0;        // the line model's rate (0: no model, the fixed timeout alone)
  int retries = 5;     // resends of the oldest unanswered request before the link is down
};

// What a stream counts (Link adds it to its stats).
struct SenderCounters {
  uint64_t requests = 0, retransmissions = 0, timeouts = 0, probes = 0;
};

// Requests sent in order with up to `window` in flight. Every copy written is numbered; an answer or NAK is
// attributed to a copy by counting (the k-th event naming a request is about its k-th copy or a later one) and
// shows every unanswered request, not held, whose latest copy went out before that copy lost it: those are sent
// again at once, and so is a request NAKed SEQ_GAP/UNKNOWN_TYPE about its latest copy. A NAK HELD marks the request
// held (the firmware runs it once the gap before it is filled): not sent again; an answer shows every request before
// it ran, so a held one still unanswered lost its answer and is sent again. BAD_CRC and BAD_LENGTH NAKs (their SEQ
// read from damaged bytes) are not counted; naming the oldest unanswered request they send that again. A write after
// which nothing more can go out (window full, or the last request written) that carries resends or the last request
// is followed by a probe (PROTOCOL.md "Probe": TYPE NAK, no payload, the SEQ before the oldest unanswered request).
// Silence past deadline() sends every unanswered request again, oldest first, held ones included.
class WindowSender {
 public:
  using Clock = std::chrono::steady_clock;

  // One request each: its type, SEQ and frame size on the wire.
  WindowSender(std::vector<uint8_t> types, std::vector<uint8_t> seqs, std::vector<uint8_t> sizes,
               SenderSettings settings);

  // The first write.
  std::vector<SenderWrite> start(Clock::time_point now);
  // A frame received: marks what it shows lost. True when it was about this stream (an answer or a NAK of a request
  // in flight, or a probe's NAK); false for the caller to match elsewhere or count as stale.
  bool feed(const rbx1_frame& f);
  // After the frames received: the oldest answered ones leave the window, the requests shown lost (or, on a silence
  // past the deadline, every unanswered one) are sent again, and new ones go out if there is room.
  std::vector<SenderWrite> step(Clock::time_point now);
  // The first part of step(): the oldest answered requests leave the window (the stream ends without the rest).
  void advance(Clock::time_point now);
  // When silence about the oldest unanswered request sends the window again (PROTOCOL.md "Timeout").
  Clock::time_point deadline() const;
  // Something for step() to do before the deadline: the oldest answered, a request to send again, room, an error.
  bool ready() const;
  bool finished() const { return base_ == n_ || error_; }
  // 0, or why the stream ended: -ETIMEDOUT (the oldest unanswered after every resend), -EPROTO (NAK SEQ_OLD),
  // -EOPNOTSUPP (NAK UNKNOWN_TYPE of a type that is no request).
  int error() const { return error_; }
  size_t oldest() const { return base_; }
  uint8_t type(size_t i) const { return req_[i].type; }
  uint8_t seq(size_t i) const { return req_[i].seq; }
  bool timed_out() const { return timed_out_; }  // the last step's resends came from a silence
  bool answered(size_t i) const { return req_[i].done; }
  const uint8_t* response(size_t i) const { return req_[i].resp; }
  uint8_t response_len(size_t i) const { return req_[i].resp_len; }
  const SenderCounters& counters() const { return counters_; }

 private:
  struct Request {
    uint8_t type = 0, seq = 0, size = 0, answer_size = 0;
    bool done = false;
    uint8_t resp_len = 0;
    uint8_t resp[RBX1_MAX_PAYLOAD] = {};
    std::vector<uint32_t> txs;  // each copy's place in the order of all copies written
    uint32_t events = 0;        // answers and NAKs naming it (the k-th is about copy k or later)
    bool resend = false;        // shown lost: goes again in this step
    bool held = false;          // the firmware holds it (NAK HELD): not lost, not resent until a timeout
    bool by_release = false;    // resend because a held request's answer showed its answer lost
    uint32_t release_copy = 0;  // the copy that resend wrote (the other answers of that release show nothing newer)
    Clock::time_point sent_at, due;  // the latest copy's time, and when its answer is due on the line model
  };

  size_t room() const;
  std::vector<SenderWrite> fresh(Clock::time_point now);
  std::vector<size_t> resends(Clock::time_point now);
  SenderWrite send(std::vector<size_t> which, bool resent, Clock::time_point now);
  Clock::time_point model(size_t out, size_t back);
  void mark(size_t i) { req_[i].resend = true; }
  bool feed_probe(const rbx1_frame& f);
  void on_probe(uint32_t copy);
  uint32_t counted_copy(size_t i);
  void on_nak(size_t i, uint8_t reason);
  void on_answer(size_t i, const rbx1_frame& f);
  void lost_before(size_t i, uint32_t copy);
  bool unanswered(size_t i) const { return !req_[i].done; }

  std::vector<Request> req_;
  SenderSettings s_;
  size_t n_;
  std::chrono::duration<double> byte_time_;
  Clock::time_point line_out_{}, line_back_{};  // when the bytes written so far are out: to the firmware, and back
  std::deque<std::pair<uint8_t, uint32_t>> probes_;  // (SEQ, copy number) of the probes whose NAK has not come
  uint32_t tx_ = 0;    // copies written
  uint32_t seen_ = 0;  // the latest copy an answer or NAK was about: the copies after it are on the line
  size_t base_ = 0, next_ = 0;
  int tries_ = 0, silences_ = 0;  // silences: timeouts since the oldest unanswered request changed
  Clock::time_point oldest_since_{};
  int error_ = 0;
  bool timed_out_ = false;
  SenderCounters counters_;
};

}  // namespace rbx1::link
