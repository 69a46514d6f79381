// window_sender.cpp - the window sender's steps: writes, attribution of answers and NAKs to copies, probes, the
// line model's deadline, resends (PROTOCOL.md "Window", "Probe", "Pacing", "Timeout").
#include "window_sender.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rbx1::link {

WindowSender::WindowSender(std::vector<uint8_t> types, std::vector<uint8_t> seqs, std::vector<uint8_t> sizes,
                           SenderSettings settings)
    : req_(types.size()), s_(settings), n_(types.size()),
      byte_time_(settings.baud > 0 ? 10.0 / settings.baud : 0.0) {
  s_.window = std::max<size_t>(1, s_.window);
  for (size_t i = 0; i < n_; ++i) {
    req_[i].type = types[i];
    req_[i].seq = seqs[i];
    req_[i].size = sizes[i];
    req_[i].answer_size = static_cast<uint8_t>(RBX1_FRAME_OVERHEAD + std::max(0, rbx1_response_len(types[i])));
  }
}

std::vector<SenderWrite> WindowSender::start(Clock::time_point now) {
  oldest_since_ = now;
  return fresh(now);
}

// New requests go out as answers come back (PROTOCOL.md "Pacing"): at most `ahead` copies beyond the latest one an
// answer or NAK was about, so a resend waits behind a few frames, not the whole window.
size_t WindowSender::room() const {
  size_t r = std::min(n_, base_ + s_.window) - next_;
  if (s_.window > 1 && s_.ahead) r = std::min<size_t>(r, tx_ - seen_ >= s_.ahead ? 0 : s_.ahead - (tx_ - seen_));
  return r;
}

std::vector<SenderWrite> WindowSender::fresh(Clock::time_point now) {
  const size_t k = room();
  if (next_ >= n_ || k == 0) return {};
  std::vector<size_t> which;
  for (size_t i = 0; i < k; ++i) which.push_back(next_ + i);
  next_ += k;
  return {send(std::move(which), false, now)};
}

// The line model (PROTOCOL.md "Timeout"): a frame written now arrives after the bytes written before it, and its
// answer goes back after it arrived and after the answers before it; returns when that answer is out.
WindowSender::Clock::time_point WindowSender::model(size_t out, size_t back) {
  line_out_ += std::chrono::duration_cast<Clock::duration>(byte_time_ * static_cast<double>(out));
  line_back_ = std::max(line_back_, line_out_) +
               std::chrono::duration_cast<Clock::duration>(byte_time_ * static_cast<double>(back));
  return line_back_;
}

// The copies get their places in the order before an answer to them can be fed. A write after which nothing more
// can go out until answers come (window full, or the last request written) that carries resends or the last
// request is followed by a probe (PROTOCOL.md "Probe").
SenderWrite WindowSender::send(std::vector<size_t> which, bool resent, Clock::time_point now) {
  line_out_ = std::max(line_out_, now);
  for (size_t i : which) {
    Request& r = req_[i];
    r.txs.push_back(++tx_);
    r.sent_at = now;
    r.due = model(r.size, r.answer_size);
    r.resend = false;
    if (r.by_release) r.release_copy = tx_;
    r.by_release = false;
  }
  SenderWrite w{std::move(which)};
  if (s_.window > 1 && (resent || next_ == n_) && (next_ == n_ || next_ - base_ >= s_.window)) {
    w.probe = true;
    w.probe_seq = static_cast<uint8_t>(req_[base_].seq - 1);  // never in flight
    model(RBX1_FRAME_OVERHEAD, RBX1_FRAME_OVERHEAD + RBX1_NAK_LEN);
    probes_.emplace_back(w.probe_seq, ++tx_);
    counters_.probes++;
  }
  return w;
}

// When silence about the oldest unanswered request sends the window again: a quarter of the timeout, doubled by each
// silence since it became the oldest, after its latest copy's answer is due on the line model or after it became
// the oldest (a held request's answer follows the filler's), whichever is later, and never after the timeout. The
// slow types (EEPROM writes) wait their own time.
WindowSender::Clock::time_point WindowSender::deadline() const {
  const Request& r = req_[base_];
  if (r.type == RBX1_MSG_CONFIG_SET || r.type == RBX1_MSG_CONFIG_RESET)
    return r.sent_at + std::chrono::milliseconds(std::max(s_.timeout_ms, 1000));
  const auto late = r.sent_at + std::chrono::milliseconds(s_.timeout_ms);
  if (s_.baud <= 0) return late;
  const auto margin = std::chrono::microseconds(s_.timeout_ms * 250LL << std::min(silences_, 8));
  return std::min(late, std::max(r.due, oldest_since_) + margin);
}

bool WindowSender::ready() const {
  if (finished() || req_[base_].done || room() > 0) return true;
  for (size_t i = base_; i < next_; ++i)
    if (unanswered(i) && req_[i].resend) return true;
  return false;
}

bool WindowSender::feed(const rbx1_frame& f) {
  if (error_ || base_ == n_) return false;
  if (feed_probe(f)) return true;
  const size_t k = static_cast<uint8_t>(f.seq - req_[base_].seq);
  if (k >= next_ - base_) return false;  // not in flight: a late copy of an earlier answer
  const size_t i = base_ + k;
  if (req_[i].done) return false;  // about a request already answered
  if (f.type == RBX1_MSG_NAK) {
    rbx1_nak nak{};
    on_nak(i, f.len == RBX1_NAK_LEN && rbx1_nak_unpack(&nak, f.payload, f.len) == RBX1_OK ? nak.reason : 0xFF);
    return true;
  }
  if (f.type != RBX1_RESPONSE(req_[i].type)) return false;  // another type with this SEQ
  on_answer(i, f);
  return true;
}

// A probe's NAK (UNKNOWN_TYPE with a probe's SEQ): the oldest probe with this SEQ is the earliest it can answer;
// older ones still waiting were lost.
bool WindowSender::feed_probe(const rbx1_frame& f) {
  rbx1_nak nak{};
  if (f.type != RBX1_MSG_NAK || f.len != RBX1_NAK_LEN || rbx1_nak_unpack(&nak, f.payload, f.len) != RBX1_OK ||
      nak.reason != RBX1_UNKNOWN_TYPE)
    return false;
  auto it = std::find_if(probes_.begin(), probes_.end(), [&](const auto& p) { return p.first == f.seq; });
  if (it == probes_.end()) return false;
  const uint32_t copy = it->second;
  probes_.erase(probes_.begin(), it + 1);
  on_probe(copy);
  return true;
}

// Answered after every copy written before it: each unanswered request, not held, whose latest copy went out
// before the probe lost it.
void WindowSender::on_probe(uint32_t copy) {
  seen_ = std::max(seen_, copy);
  for (size_t j = base_; j < next_; ++j)
    if (unanswered(j) && !req_[j].held && req_[j].txs.back() < copy) mark(j);
}

uint32_t WindowSender::counted_copy(size_t i) {
  Request& r = req_[i];
  ++r.events;
  return r.txs[std::min<size_t>(r.events, r.txs.size()) - 1];
}

void WindowSender::on_nak(size_t i, uint8_t reason) {
  Request& r = req_[i];
  if (reason != RBX1_HELD && reason != RBX1_SEQ_GAP && reason != RBX1_UNKNOWN_TYPE && reason != RBX1_SEQ_OLD) {
    // BAD_CRC, BAD_LENGTH: its SEQ was read from damaged bytes and may name another request, so it is not counted;
    // naming the oldest unanswered one it sends that again (at worst a copy answered from memory).
    size_t oldest = base_;
    while (oldest < next_ && req_[oldest].done) ++oldest;
    if (i == oldest) mark(i);
    return;
  }
  const uint32_t copy = counted_copy(i);
  seen_ = std::max(seen_, copy);
  if (reason == RBX1_SEQ_OLD) {  // a SEQ of the past: resending cannot help
    error_ = -EPROTO;
    return;
  }
  if (reason == RBX1_UNKNOWN_TYPE && rbx1_request_len(r.type) < 0) {  // no request type: resending cannot help
    error_ = -EOPNOTSUPP;
    return;
  }
  r.held = reason == RBX1_HELD;  // a SEQ_GAP after HELD: the firmware dropped it (ESTOP)
  if (r.held)
    r.resend = false;
  else if (copy == r.txs.back())
    mark(i);  // its latest copy was refused
  lost_before(i, copy);
}

// The firmware runs requests in SEQ order: every unanswered request before this one ran and its answer, sent
// before this one, was lost: those held, or all of them when this one was held, are sent again (answered from
// memory). A held request's answer follows the answer of the request that filled the gap, not its own copy, so it
// tells nothing by copies (and a request sent again for one answer of a release is not sent again for the others).
void WindowSender::on_answer(size_t i, const rbx1_frame& f) {
  Request& r = req_[i];
  r.done = true;
  r.resend = false;
  r.resp_len = f.len;
  std::memcpy(r.resp, f.payload, f.len);
  const uint32_t copy = counted_copy(i);
  for (size_t j = base_; j < i; ++j) {
    Request& o = req_[j];
    if (o.done || !(o.held || r.held)) continue;
    if (!o.held && o.release_copy == o.txs.back()) continue;  // already sent again for this release
    o.held = false;
    mark(j);
    o.by_release = true;
  }
  if (r.held) return;
  seen_ = std::max(seen_, copy);
  lost_before(i, copy);
}

// Answers and NAKs come in frame order: an unanswered request, not held, whose latest copy went out before this
// copy lost it (the frame, or its answer).
void WindowSender::lost_before(size_t i, uint32_t copy) {
  for (size_t j = base_; j < next_; ++j)
    if (j != i && unanswered(j) && !req_[j].held && req_[j].txs.back() < copy) mark(j);
}

void WindowSender::advance(Clock::time_point now) {
  if (base_ == n_ || !req_[base_].done) return;
  while (base_ < next_ && req_[base_].done) {
    ++base_;
    counters_.requests++;
  }
  tries_ = silences_ = 0;
  oldest_since_ = now;
  if (base_ == next_) seen_ = tx_;  // every request written is answered: what was left on the line no longer counts
}

std::vector<SenderWrite> WindowSender::step(Clock::time_point now) {
  timed_out_ = false;
  if (error_) return {};
  advance(now);
  if (base_ == n_) return {};
  std::vector<SenderWrite> writes;
  std::vector<size_t> again = resends(now);
  if (!again.empty()) {
    if (again.front() == base_ && ++tries_ > s_.retries) {
      error_ = -ETIMEDOUT;
      return {};
    }
    counters_.retransmissions += again.size();
    writes.push_back(send(std::move(again), true, now));
  }
  for (SenderWrite& w : fresh(now)) writes.push_back(std::move(w));
  return writes;
}

// The requests shown lost, oldest first; none and silence past the deadline: every unanswered one.
std::vector<size_t> WindowSender::resends(Clock::time_point now) {
  std::vector<size_t> again;
  for (size_t i = base_; i < next_; ++i) {
    if (unanswered(i) && req_[i].resend) again.push_back(i);
    req_[i].resend = false;
  }
  if (!again.empty() || base_ >= next_ || now < deadline()) return again;
  timed_out_ = true;
  counters_.timeouts++;
  ++silences_;
  for (size_t i = base_; i < next_; ++i)
    if (unanswered(i)) again.push_back(i);
  return again;
}

}  // namespace rbx1::link
