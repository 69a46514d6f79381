// link_stream.cpp - a Link's windowed streams: the I/O around the window sender (window_sender.cpp decides,
// this writes and waits), and MOVE streams.
#include "link.hpp"

#include <array>
#include <cerrno>
#include <cstring>

#include <spdlog/spdlog.h>

#include "window_sender.hpp"

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

int Link::stream(std::vector<StreamRequest>& reqs) {
  const size_t n = reqs.size();
  if (n == 0) return 0;
  std::lock_guard<std::mutex> request_lock(request_mu_);
  if (int r = resync_locked(); r < 0) return r;
  std::vector<uint8_t> types(n), seqs(n), sizes(n);
  std::vector<std::array<uint8_t, RBX1_MAX_FRAME>> frames(n);
  const size_t win = static_cast<size_t>(window());
  {
    std::lock_guard<std::mutex> lock(state_mu_);
    if (!connected_) return down_error();
    for (size_t i = 0; i < n; ++i) {
      reqs[i].answered = false;
      types[i] = reqs[i].type;
      seqs[i] = next_seq_++;
    }
  }
  for (size_t i = 0; i < n; ++i) {
    sizes[i] = static_cast<uint8_t>(
        rbx1_frame_encode(frames[i].data(), RBX1_MAX_FRAME, seqs[i], reqs[i].type, reqs[i].payload, reqs[i].len));
    if (!sizes[i]) return -EINVAL;
  }
  // The line model runs at the port's rate (opened with open_fd: none, the fixed timeout alone).
  WindowSender sender(types, seqs, sizes,
                      {win, static_cast<uint32_t>(ahead_.load()), timeout_ms_.load(), baud_, retries_.load()});
  int result = run_stream(sender, frames, sizes);
  // Unanswered SEQs (after an unknown type: every later one) would be gaps in the firmware's order.
  if (result == -ETIMEDOUT || result == -EPROTO || result == -EOPNOTSUPP) resync_ = true;
  for (size_t i = 0; i < n; ++i) {
    reqs[i].answered = sender.answered(i);
    reqs[i].resp_len = sender.response_len(i);
    std::memcpy(reqs[i].resp, sender.response(i), reqs[i].resp_len);
  }
  return result;
}

// The stream's I/O: each write the sender decides goes on the wire (the lock released meanwhile, the copies already
// numbered so that the reader can attribute their answers), then a wait until the reader gave the sender something
// to act on or its deadline passed. 0, or a negative errno.
int Link::run_stream(WindowSender& sender, const std::vector<std::array<uint8_t, RBX1_MAX_FRAME>>& frames,
                     const std::vector<uint8_t>& sizes) {
  std::unique_lock<std::mutex> lock(state_mu_);
  stream_ = &sender;
  SenderCounters counted;
  int result = write_stream(sender.start(Clock::now()), frames, sizes, lock);
  while (result == 0 && !sender.finished()) {
    state_cv_.wait_until(lock, sender.deadline(), [&] { return sender.ready() || !connected_; });
    if (!connected_) {
      sender.advance(Clock::now());
      result = down_error();
      break;
    }
    std::vector<SenderWrite> writes = sender.step(Clock::now());
    count_stream(sender, counted);
    if (sender.error() == -ETIMEDOUT) {
      counters_.link_down++;
      spdlog::warn("{}: link down: type 0x{:02x} seq {} unanswered after {} retransmissions", name_,
                   sender.type(sender.oldest()), sender.seq(sender.oldest()), retries_.load());
    }
    result = sender.error() ? sender.error() : write_stream(writes, frames, sizes, lock);
  }
  count_stream(sender, counted);
  stream_ = nullptr;
  return result;
}

// Adds what the sender counted since the last call to the link's stats; a request answered counts as done for the
// heartbeat.
void Link::count_stream(const WindowSender& sender, SenderCounters& counted) {
  const SenderCounters& now = sender.counters();
  if (now.requests > counted.requests) last_done_ = Clock::now();
  counters_.requests += now.requests - counted.requests;
  counters_.retransmissions += now.retransmissions - counted.retransmissions;
  counters_.timeouts += now.timeouts - counted.timeouts;
  counters_.probes += now.probes - counted.probes;
  if (now.retransmissions > counted.retransmissions)
    spdlog::debug("{}: resending {} frames ({})", name_, now.retransmissions - counted.retransmissions,
                  sender.timed_out() ? "timeout" : "lost copies");
  counted = now;
}

// Writes each of writes as one burst (the requests' frames, then the probe). Under state_mu_ (released while
// writing).
int Link::write_stream(const std::vector<SenderWrite>& writes,
                       const std::vector<std::array<uint8_t, RBX1_MAX_FRAME>>& frames,
                       const std::vector<uint8_t>& sizes, std::unique_lock<std::mutex>& lock) {
  std::vector<uint8_t> burst;
  for (const SenderWrite& w : writes) {
    burst.clear();
    for (size_t i : w.frames) burst.insert(burst.end(), frames[i].begin(), frames[i].begin() + sizes[i]);
    if (w.probe) {
      uint8_t probe[RBX1_MAX_FRAME];
      const size_t len = rbx1_frame_encode(probe, sizeof probe, w.probe_seq, RBX1_MSG_NAK, nullptr, 0);
      burst.insert(burst.end(), probe, probe + len);
    }
    lock.unlock();
    int r = write_frame(burst.data(), burst.size());
    lock.lock();
    if (r < 0) return r;
  }
  return 0;
}

int Link::move_stream(const std::vector<rbx1_move_req>& reqs, std::vector<rbx1_move_resp>& out,
                      std::vector<bool>& answered) {
  std::vector<StreamRequest> s(reqs.size());
  for (size_t i = 0; i < reqs.size(); ++i) {
    s[i].type = RBX1_MSG_MOVE;
    s[i].len = rbx1_move_req_pack(&reqs[i], s[i].payload);
  }
  int r = stream(s);
  out.assign(reqs.size(), rbx1_move_resp{});
  answered.assign(reqs.size(), false);
  for (size_t i = 0; i < reqs.size(); ++i) {
    if (!s[i].answered) continue;
    answered[i] = true;
    if (rbx1_move_resp_unpack(&out[i], s[i].resp, s[i].resp_len) != RBX1_OK) {
      if (s[i].resp_len < 1) return -EBADMSG;
      out[i].status = s[i].resp[0];  // a refusal may carry the status alone
    }
  }
  return r;
}

}  // namespace rbx1::link
