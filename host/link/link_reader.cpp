// link_reader.cpp - a Link's reader thread: every byte decoded, each frame handed to the stream in progress, the
// request or the e-stop waiting for it; a vanished port noticed at once.
#include "link.hpp"

#include <cerrno>
#include <cstring>
#include <poll.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "window_sender.hpp"

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

namespace {

// Protocol version 3's CRC-16/CCITT-FALSE, only to recognise a firmware of that version (below).
uint16_t crc16_v3(const uint8_t* p, size_t n) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < n; i++) {
    uint8_t x = static_cast<uint8_t>((crc >> 8) ^ p[i]);
    x ^= static_cast<uint8_t>(x >> 4);
    crc = static_cast<uint16_t>((crc << 8) ^ (x << 12) ^ (x << 5) ^ x);
  }
  return crc;
}

// A frame a version 3 firmware sends (a NAK or a response, CRC-16 and 6 bytes of framing) among the bytes. Such a
// firmware NAKs our HELLO BAD_CRC (it reads its CRC-32 as a CRC-16) in frames our decoder cannot read.
bool has_v3_frame(const std::vector<uint8_t>& b) {
  for (size_t i = 0; i + 6 <= b.size(); i++) {
    size_t len = b[i + 1];
    if (b[i] != RBX1_SYNC || len > RBX1_MAX_PAYLOAD || i + len + 6 > b.size()) continue;
    if (b[i + 3] != RBX1_MSG_NAK && !(b[i + 3] & 0x80)) continue;
    if (crc16_v3(&b[i + 1], len + 3) == (b[i + len + 4] | (b[i + len + 5] << 8))) return true;
  }
  return false;
}

}  // namespace

void Link::reader_loop(int fd, int wake) {
  constexpr int kInterByteMs = 50;  // PROTOCOL.md: a partial frame older than this is dropped
  pollfd fds[2] = {{fd, POLLIN, 0}, {wake, POLLIN, 0}};
  auto last_rx = Clock::now();
  uint8_t buf[256];
  for (;;) {
    int timeout = rbx1_decoder_pending(&decoder_) ? kInterByteMs : -1;
    int n = poll(fds, 2, timeout);
    if (n < 0) {
      if (errno == EINTR) continue;
      port_gone(errno);
      return;
    }
    if (fds[1].revents) return;  // detach()
    if (n == 0) {
      if (Clock::now() - last_rx >= std::chrono::milliseconds(kInterByteMs) && rbx1_decoder_reset(&decoder_))
        spdlog::debug("{}: dropped a partial frame (inter-byte timeout)", name_);
      continue;
    }
    if (fds[0].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL)) {
      ssize_t got = ::read(fd, buf, sizeof buf);
      if (got > 0) {
        last_rx = Clock::now();
        counters_.bytes_received += static_cast<uint64_t>(got);
        rbx1_decoder_feed(&decoder_, buf, static_cast<size_t>(got));
        if (handshaking_ && !v3_seen_) {  // the last 128 bytes, searched for a version 3 firmware's frames
          recent_.insert(recent_.end(), buf, buf + got);
          if (recent_.size() > 128) recent_.erase(recent_.begin(), recent_.end() - 128);
          if (has_v3_frame(recent_)) v3_seen_ = true;
        }
        continue;
      }
      if (got < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      // EOF on a tty means hang-up (the USB device or the pty's other side went away).
      port_gone(got == 0 ? ENODEV : errno);
      return;
    }
  }
}

void Link::port_gone(int err) {
  {
    std::lock_guard<std::mutex> lock(state_mu_);
    if (!connected_) return;
    connected_ = false;
    gone_error_ = err;
  }
  spdlog::warn("{}: port gone ({}); waiting for reconnect", name_, std::strerror(err));
  state_cv_.notify_all();
}

// Under state_mu_: a stream in progress (WindowSender) is told of every frame first; what it does not claim is matched
// with the single request or the e-stop waiting.
void Link::on_frame(void* ctx, const rbx1_frame* f) {
  Link* self = static_cast<Link*>(ctx);
  std::unique_lock<std::mutex> lock(self->state_mu_);
  if (f->type == RBX1_MSG_NAK) {
    self->counters_.naks++;
    rbx1_nak nak{};
    rbx1_nak_unpack(&nak, f->payload, f->len);
    spdlog::debug("{}: NAK {} for seq {}", self->name_, rbx1_status_name(nak.reason), f->seq);
    if (!(self->stream_ && self->stream_->feed(*f))) {
      auto mark = [&](Waiter* w) {
        // HELD: kept by the firmware until the gap before it is filled; wait for the answer.
        if (w && !w->done && w->seq == f->seq && nak.reason != RBX1_HELD) {
          w->nak = true;
          w->nak_reason = nak.reason;
        }
      };
      for (Waiter* w : self->waiting_) mark(w);
      mark(self->estop_waiting_);
    }
    lock.unlock();
    self->state_cv_.notify_all();
    return;
  }
  auto take = [&](Waiter* w) {
    if (!w || w->done || w->seq != f->seq || f->type != RBX1_RESPONSE(w->type)) return false;
    w->done = true;
    w->len = f->len;
    std::memcpy(w->payload, f->payload, f->len);
    return true;
  };
  bool ours = take(self->estop_waiting_) || (self->stream_ && self->stream_->feed(*f));
  for (size_t i = 0; !ours && i < self->waiting_.size(); ++i) ours = take(self->waiting_[i]);
  if (ours) {
    lock.unlock();
    self->state_cv_.notify_all();
    return;
  }
  // A late duplicate of an answered request, or a response to one given up on: not ours to act on.
  self->counters_.stale++;
  spdlog::debug("{}: discarded stale frame type 0x{:02x} seq {}", self->name_, f->type, f->seq);
}

void Link::on_reject(void* ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  Link* self = static_cast<Link*>(ctx);
  self->counters_.rejected++;
  if (has_seq)
    spdlog::debug("{}: rejected a received frame ({}, seq {})", self->name_, rbx1_status_name(status), seq);
  else
    spdlog::debug("{}: rejected a received frame ({})", self->name_, rbx1_status_name(status));
}

}  // namespace rbx1::link
