// link.cpp - requests one at a time and windowed streams, retransmission (selective repeat), answer matching, e-stop,
// reconnect (PROTOCOL.md).
#include "link.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <poll.h>
#include <random>
#include <sys/eventfd.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "serial_port.hpp"

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

void parse_link_config(rbx1::config::Section link, LinkConfig& out) {
  out.port = link.string("port", out.port);
  if (link.has("port") && out.port.empty()) link.errors().add(link.path() + ".port", "must not be empty");
  int64_t baud = link.integer("baud", out.baud, 1, 4000000);
  if (!supported_baud(static_cast<int>(baud)))
    link.errors().add(link.path() + ".baud", "must be 115200, 230400 or 250000, got " + std::to_string(baud));
  else
    out.baud = static_cast<int>(baud);
  out.timeout_ms = static_cast<int>(link.integer("timeout_ms", out.timeout_ms, 10, 5000));
  out.retries = static_cast<int>(link.integer("retries", out.retries, 0, 20));
  out.heartbeat_ms = static_cast<int>(link.integer("heartbeat_ms", out.heartbeat_ms, 20, 30000));
  out.boot_wait_ms = static_cast<int>(link.integer("boot_wait_ms", out.boot_wait_ms, 0, 10000));
  out.window = static_cast<int>(link.integer("window", out.window, 1, 64));
  link.reject_unknown();
}

Link::Link() {
  std::random_device rd;  // a fresh host starts at a random SEQ so it cannot replay the firmware's last frame
  next_seq_ = static_cast<uint8_t>(rd());
  last_done_ = Clock::now();
}

Link::~Link() { close(); }

void Link::set_timing(int timeout_ms, int retries) {
  std::lock_guard<std::mutex> lock(request_mu_);
  timeout_ms_ = timeout_ms;
  retries_ = retries;
}

void Link::set_window(int max_in_flight) { max_window_ = std::max(1, max_in_flight); }

void Link::set_ahead(int frames) { ahead_ = std::max(0, frames); }

int Link::window() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  if (!hello_.window) return 1;
  return std::min<int>(hello_.window, max_window_);
}

int Link::open(const LinkConfig& config, std::string& error) {
  set_timing(config.timeout_ms, config.retries);
  set_window(config.window);
  set_boot_wait(config.boot_wait_ms);
  return open(config.port, config.baud, error);
}

int Link::open(const std::string& port, int baud, std::string& error) {
  close();
  path_ = name_ = port;
  baud_ = baud;
  int fd = open_serial(port, baud, error);
  if (fd < 0) return fd;
  return attach(fd, error);
}

int Link::open_fd(int fd, const std::string& name, std::string& error) {
  close();
  path_.clear();
  name_ = name;
  baud_ = 0;
  return attach(fd, error);
}

int Link::attach(int fd, std::string& error) {
  int wake = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake < 0) {
    int e = errno;
    ::close(fd);
    error = name_ + ": eventfd: " + std::strerror(e);
    return -e;
  }
  {
    std::scoped_lock lock(write_mu_, state_mu_);
    fd_ = fd;
    wake_fd_ = wake;
    gone_error_ = 0;
    connected_ = true;
  }
  rbx1_decoder_init(&decoder_, &Link::on_frame, &Link::on_reject, this);
  recent_.clear();
  v3_seen_ = false;
  reader_ = std::thread(&Link::reader_loop, this, fd, wake);
  int r = handshake(error);
  if (r < 0) detach();
  return r;
}

// A Mega that the open reset (DTR) or that was just plugged in sits in its stk500v2 bootloader for 0.83 s; a byte
// arriving then (our HELLO) keeps it there until 5.2 s pass without one (measured: tools/flashsim/README.md).
// So after an unanswered HELLO exchange the link keeps quiet this long before asking again; repeating HELLO
// would hold the board in its bootloader forever.
constexpr auto kBootloaderQuiet = std::chrono::milliseconds(6000);

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

int Link::handshake(std::string& error) {
  rbx1_hello_resp h{};
  auto deadline = Clock::now() + std::chrono::milliseconds(boot_wait_ms_.load());
  handshaking_ = true;
  int r = hello(h);
  while (r == -ETIMEDOUT && !v3_seen_ && Clock::now() < deadline) {
    auto quiet = std::min<Clock::duration>(kBootloaderQuiet, deadline - Clock::now());
    spdlog::info("{}: no HELLO answer yet; quiet for {} ms so a board in its bootloader starts the firmware", name_,
                 std::chrono::duration_cast<std::chrono::milliseconds>(quiet).count());
    std::this_thread::sleep_for(quiet);
    r = hello(h);
  }
  handshaking_ = false;
  if (r == -ETIMEDOUT && v3_seen_) {
    error = name_ + ": firmware speaks protocol version 3 (CRC-16 frames: it NAKs every frame of ours), this host " +
            std::to_string(RBX1_PROTO_VERSION) + "; flash the matching firmware: rbx1-flash " + name_ +
            " (from a checkout: make flash PORT=" + name_ + ")";
    return -EPROTO;
  }
  if (r == -EPROTO) {
    error = name_ + ": firmware speaks protocol version " + std::to_string(h.proto_version) + ", this host " +
            std::to_string(RBX1_PROTO_VERSION) + "; flash the matching firmware: rbx1-flash " + name_ +
            " (from a checkout: make flash PORT=" + name_ + ")";
    return r;
  }
  if (r < 0) {
    error = name_ + ": no HELLO response (" + std::strerror(-r) + ")";
    return r;
  }
  if (h.status != RBX1_OK) {
    error = name_ + ": HELLO refused: " + rbx1_status_name(h.status);
    return -EPROTO;
  }
  spdlog::info("{}: firmware {}.{}.{}, {} joints, queue {}, window {}, capabilities 0x{:04x}, continuing at seq {}",
               name_, h.fw_major, h.fw_minor, h.fw_patch, h.joints, h.queue_size, h.window, h.capabilities,
               next_seq());
  return 0;
}

void Link::detach() {
  int fd, wake;
  {
    std::scoped_lock lock(write_mu_, state_mu_);
    fd = fd_;
    wake = wake_fd_;
    fd_ = wake_fd_ = -1;
    connected_ = false;
    if (!gone_error_) gone_error_ = ENOTCONN;
  }
  state_cv_.notify_all();
  if (wake >= 0) {
    uint64_t one = 1;
    if (::write(wake, &one, sizeof one) < 0) spdlog::debug("{}: eventfd write: {}", name_, std::strerror(errno));
  }
  if (reader_.joinable()) reader_.join();
  if (fd >= 0) ::close(fd);
  if (wake >= 0) ::close(wake);
}

void Link::close() {
  stop_heartbeat();
  std::lock_guard<std::mutex> lock(request_mu_);
  detach();
}

int Link::reconnect(std::string& error) {
  if (path_.empty()) {
    error = name_ + ": opened from an fd, cannot be reopened";
    return -EOPNOTSUPP;
  }
  {
    std::lock_guard<std::mutex> lock(request_mu_);
    detach();
  }
  int fd = open_serial(path_, baud_, error);
  if (fd < 0) return fd;
  int r = attach(fd, error);
  if (r == 0) {
    counters_.reconnects++;
    spdlog::info("{}: reconnected", name_);
  }
  return r;
}

int Link::wait_reconnect(int timeout_ms, std::string& error) {
  auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    int r = reconnect(error);
    if (r == 0 || Clock::now() >= deadline) return r;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

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

// A stream's retransmission rule (PROTOCOL.md "Window"), under state_mu_: the firmware answers what it receives in
// order, so an answer or NAK about one copy of w shows that every unanswered request, not held, whose latest copy
// went out before that copy lost it (the frame or its answer); a NAK about w's latest copy refuses that copy too (a
// NAK HELD does not: the firmware keeps it). The k-th answer or NAK naming w is about its k-th copy or a later one:
// the earliest it can be about is the one used.
void Link::attribute(Waiter* w, bool refused) {
  if (w->txs.empty()) return;  // a single request (transact): its own rule
  ++w->events;
  uint32_t copy = w->txs[std::min<size_t>(w->events, w->txs.size()) - 1];
  seen_tx_ = std::max(seen_tx_, copy);
  if (refused && copy == w->txs.back()) w->resend = true;
  if (w->held) w->resend = false;
  for (Waiter* o : waiting_)
    if (o != w && !o->done && !o->held && !o->txs.empty() && o->txs.back() < copy) o->resend = true;
}

// An answer to w in a stream: the firmware runs requests in SEQ order, so every unanswered request before w (in
// waiting_, oldest first) ran and its answer, sent before w's, was lost: those held, or all of them when w was
// held, are sent again (answered from memory). A held request's answer follows the answer of the request that
// filled the gap, not its own copy, so it tells nothing by copies (and a request sent again for one answer of a
// release is not sent again for the others); any other answer is attributed as above.
void Link::attribute_answer(Waiter* w) {
  if (w->txs.empty()) return;
  for (Waiter* o : waiting_) {
    if (o == w) break;
    if (o->done || !(o->held || w->held)) continue;
    if (!o->held && !o->txs.empty() && o->release_copy == o->txs.back()) continue;  // already sent again for this
    o->held = false;
    o->resend = true;
    o->release_resend = true;
  }
  if (!w->held) attribute(w, false);
}

void Link::on_frame(void* ctx, const rbx1_frame* f) {
  Link* self = static_cast<Link*>(ctx);
  std::unique_lock<std::mutex> lock(self->state_mu_);
  if (f->type == RBX1_MSG_NAK) {
    self->counters_.naks++;
    rbx1_nak nak{};
    rbx1_nak_unpack(&nak, f->payload, f->len);
    if (f->len == RBX1_NAK_LEN && nak.reason == RBX1_UNKNOWN_TYPE) {
      // A stream's probe (PROTOCOL.md "Probe"): answered after every copy written before it, so each unanswered
      // request, not held, whose latest copy went out before the probe lost it. The oldest probe with this SEQ is
      // the earliest it can answer; older ones still waiting were lost.
      auto& probes = self->probes_;
      auto it = std::find_if(probes.begin(), probes.end(), [&](const auto& p) { return p.first == f->seq; });
      if (it != probes.end()) {
        const uint32_t copy = it->second;
        self->seen_tx_ = std::max(self->seen_tx_, copy);
        probes.erase(probes.begin(), it + 1);
        for (Waiter* o : self->waiting_)
          if (!o->done && !o->held && !o->txs.empty() && o->txs.back() < copy) o->resend = true;
        lock.unlock();
        self->state_cv_.notify_all();
        return;
      }
    }
    auto mark = [&](Waiter* w) {
      if (w && !w->done && w->seq == f->seq) {
        spdlog::debug("{}: NAK {} for seq {}", self->name_, rbx1_status_name(nak.reason), f->seq);
        if (nak.reason == RBX1_HELD) {  // kept by the firmware until the gap before it is filled: wait for the answer
          w->held = true;
          self->attribute(w, false);
          return;
        }
        w->held = false;  // a SEQ_GAP after HELD: the firmware dropped it (ESTOP)
        w->nak = true;
        w->nak_reason = nak.reason;
        // A BAD_CRC or BAD_LENGTH NAK carries a SEQ read from damaged bytes (it may name another request): only
        // NAKs of frames whose CRC held count.
        if (nak.reason == RBX1_SEQ_GAP || nak.reason == RBX1_UNKNOWN_TYPE) {
          self->attribute(w, true);
        } else if (!w->txs.empty()) {  // not counted; naming the oldest unanswered request it sends that again
          auto oldest = std::find_if(self->waiting_.begin(), self->waiting_.end(), [](Waiter* o) { return !o->done; });
          if (oldest != self->waiting_.end() && *oldest == w) w->resend = true;
        }
      }
    };
    for (Waiter* w : self->waiting_) mark(w);
    mark(self->estop_waiting_);
    lock.unlock();
    self->state_cv_.notify_all();
    return;
  }
  auto take = [&](Waiter* w) {
    if (!w || w->done || w->seq != f->seq || f->type != RBX1_RESPONSE(w->type)) return false;
    w->done = true;
    w->len = f->len;
    std::memcpy(w->payload, f->payload, f->len);
    self->attribute_answer(w);
    return true;
  };
  bool ours = take(self->estop_waiting_);
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

int Link::write_frame(const uint8_t* frame, size_t n) {
  std::lock_guard<std::mutex> lock(write_mu_);
  if (fd_ < 0) return -ENOTCONN;
  size_t off = 0;
  while (off < n) {
    ssize_t w = ::write(fd_, frame + off, n - off);
    if (w < 0) {
      if (errno == EINTR) continue;
      int e = errno;
      port_gone(e);
      return -e;
    }
    off += static_cast<size_t>(w);
  }
  counters_.bytes_sent += n;
  return 0;
}

// Sends frame, then waits for its response, resending the same bytes on timeout or NAK. The reader thread finds w
// in estop_waiting_ (estop) or waiting_.
int Link::transact(Waiter& w, bool estop, const uint8_t* frame, size_t n, uint8_t* resp, uint8_t& resp_len) {
  std::unique_lock<std::mutex> lock(state_mu_);
  if (!connected_) return down_error();
  if (estop)
    estop_waiting_ = &w;
  else
    waiting_.assign(1, &w);
  int result = -ETIMEDOUT;
  for (int attempt = 0; attempt <= retries_; ++attempt) {
    if (attempt > 0) {
      counters_.retransmissions++;
      spdlog::debug("{}: retransmitting type 0x{:02x} seq {} ({}/{})", name_, w.type, w.seq, attempt, retries_);
    }
    w.nak = false;
    lock.unlock();
    int r = write_frame(frame, n);
    lock.lock();
    if (r < 0 && !w.done) {
      result = r;
      break;
    }
    auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms_);
    state_cv_.wait_until(lock, deadline, [&] { return w.done || w.nak || !connected_; });
    if (w.done) {
      std::memcpy(resp, w.payload, w.len);
      resp_len = w.len;
      last_done_ = Clock::now();
      counters_.requests++;
      result = 0;
      break;
    }
    if (!connected_) {
      result = down_error();
      break;
    }
    // NAK UNKNOWN_TYPE for a request type (a damaged or stale frame: nothing ran) is a plain NAK.
    if (w.nak && w.nak_reason == RBX1_UNKNOWN_TYPE && rbx1_request_len(w.type) < 0) {
      result = -EOPNOTSUPP;
      break;
    }
    if (w.nak && w.nak_reason == RBX1_SEQ_OLD) {  // a SEQ of the past: resending it cannot help
      result = -EPROTO;
      break;
    }
    if (!w.nak) counters_.timeouts++;
  }
  if (estop)
    estop_waiting_ = nullptr;
  else
    waiting_.clear();
  if (result == -ETIMEDOUT) {
    counters_.link_down++;
    spdlog::warn("{}: link down: type 0x{:02x} seq {} unanswered after {} transmissions", name_, w.type, w.seq,
                 retries_ + 1);
  }
  return result;
}

int Link::request(uint8_t type, const uint8_t* payload, uint8_t len, uint8_t* resp, uint8_t& resp_len) {
  if (type == RBX1_MSG_ESTOP) {  // never queued behind another request
    rbx1_estop_resp out{};
    int r = estop(out);
    resp[0] = out.status;
    resp_len = 1;
    return r;
  }
  std::lock_guard<std::mutex> lock(request_mu_);
  return request_locked(type, payload, len, resp, resp_len);
}

// After a request failed unanswered, its SEQ may be missing from the firmware's order (every later one would be a
// gap): the next request starts a new session first. Under request_mu_.
int Link::resync_locked() {
  if (!resync_) return 0;
  rbx1_hello_req req{RBX1_PROTO_VERSION};
  uint8_t p[RBX1_HELLO_REQ_LEN];
  resync_ = false;
  uint8_t resp[RBX1_MAX_PAYLOAD], resp_len = 0;
  int r = request_locked(RBX1_MSG_HELLO, p, rbx1_hello_req_pack(&req, p), resp, resp_len);
  if (r < 0) return r;  // request_locked has set resync_ again
  rbx1_hello_resp h{};
  if (rbx1_hello_resp_unpack(&h, resp, resp_len) != RBX1_OK || h.status != RBX1_OK) return -EPROTO;
  std::lock_guard<std::mutex> lock(state_mu_);
  hello_ = h;
  return 0;
}

int Link::request_locked(uint8_t type, const uint8_t* payload, uint8_t len, uint8_t* resp, uint8_t& resp_len) {
  if (type != RBX1_MSG_HELLO)
    if (int r = resync_locked(); r < 0) return r;
  Waiter w;
  w.type = type;
  {
    std::lock_guard<std::mutex> lock(state_mu_);
    if (!connected_) return down_error();
    w.seq = next_seq_++;
  }
  uint8_t frame[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(frame, sizeof frame, w.seq, type, payload, len);
  if (!n) return -EINVAL;
  int r = transact(w, false, frame, n, resp, resp_len);
  if (r == -ETIMEDOUT || r == -EPROTO) resync_ = true;
  if (r == -EOPNOTSUPP) {  // an unknown type takes no place in the firmware's order: its SEQ is free again
    std::lock_guard<std::mutex> lock(state_mu_);
    if (next_seq_ == static_cast<uint8_t>(w.seq + 1)) next_seq_ = w.seq;
  }
  return r;
}

int Link::stream(std::vector<StreamRequest>& reqs) {
  const size_t n = reqs.size();
  if (n == 0) return 0;
  std::lock_guard<std::mutex> request_lock(request_mu_);
  if (int r = resync_locked(); r < 0) return r;
  std::vector<Waiter> ws(n);
  std::vector<std::array<uint8_t, RBX1_MAX_FRAME>> frames(n);
  std::vector<uint8_t> sizes(n);
  const size_t win = static_cast<size_t>(window());
  {
    std::lock_guard<std::mutex> lock(state_mu_);
    if (!connected_) return down_error();
    for (size_t i = 0; i < n; ++i) {
      reqs[i].answered = false;
      ws[i].type = reqs[i].type;
      ws[i].seq = next_seq_++;
    }
  }
  for (size_t i = 0; i < n; ++i) {
    sizes[i] = static_cast<uint8_t>(
        rbx1_frame_encode(frames[i].data(), RBX1_MAX_FRAME, ws[i].seq, reqs[i].type, reqs[i].payload, reqs[i].len));
    if (!sizes[i]) return -EINVAL;
  }
  // The timeout (PROTOCOL.md "Timeout"): a line model at the port's rate says when each copy's answer is due; the
  // bytes written so far are out at line_out towards the firmware and line_back back (baud_ 0: no model, the fixed
  // timeout alone).
  std::vector<Clock::time_point> sent_at(n), due(n);
  const std::chrono::duration<double> byte_time(baud_ > 0 ? 10.0 / baud_ : 0.0);
  Clock::time_point line_out{}, line_back{};
  auto model = [&](size_t out, size_t back) {
    line_out += std::chrono::duration_cast<Clock::duration>(byte_time * static_cast<double>(out));
    line_back = std::max(line_back, line_out) +
                std::chrono::duration_cast<Clock::duration>(byte_time * static_cast<double>(back));
    return line_back;
  };
  std::vector<uint8_t> burst;
  uint32_t tx = 0;  // copies written, in order (Waiter::txs)
  size_t base = 0, next = 0;
  // Under state_mu_: the copies get their places in the order before the reader can see an answer to them. A
  // write after which nothing more can go out until answers come (window full, or the last request written) that
  // carries resends or the last request is followed by a probe (PROTOCOL.md "Probe").
  auto send = [&](const std::vector<size_t>& which, bool resent, std::unique_lock<std::mutex>& lock) {
    burst.clear();
    for (size_t i : which) burst.insert(burst.end(), frames[i].begin(), frames[i].begin() + sizes[i]);
    auto now = Clock::now();
    line_out = std::max(line_out, now);
    for (size_t i : which) {
      sent_at[i] = now;
      due[i] = model(sizes[i], RBX1_FRAME_OVERHEAD + std::max(0, rbx1_response_len(ws[i].type)));
      ws[i].txs.push_back(++tx);
      ws[i].resend = false;
      if (ws[i].release_resend) ws[i].release_copy = tx;
      ws[i].release_resend = false;
    }
    if (win > 1 && (resent || next == n) && (next == n || next - base >= win)) {
      const uint8_t seq = static_cast<uint8_t>(ws[base].seq - 1);  // never in flight
      uint8_t probe[RBX1_MAX_FRAME];
      const size_t len = rbx1_frame_encode(probe, sizeof probe, seq, RBX1_MSG_NAK, nullptr, 0);
      burst.insert(burst.end(), probe, probe + len);
      model(len, RBX1_FRAME_OVERHEAD + RBX1_NAK_LEN);
      probes_.emplace_back(seq, ++tx);
      counters_.probes++;
    }
    lock.unlock();
    int r = write_frame(burst.data(), burst.size());
    lock.lock();
    return r;
  };
  std::unique_lock<std::mutex> lock(state_mu_);
  probes_.clear();
  seen_tx_ = 0;
  // New requests go out as answers come back (PROTOCOL.md "Pacing"): at most `ahead` copies beyond the latest one an
  // answer or NAK was about, so a resend waits behind a few frames, not the whole window.
  const uint32_t ahead = static_cast<uint32_t>(ahead_.load());
  auto room = [&] {
    size_t r = std::min(n, base + win) - next;
    if (win > 1 && ahead) r = std::min<size_t>(r, tx - seen_tx_ >= ahead ? 0 : ahead - (tx - seen_tx_));
    return r;
  };
  int tries = 0, result = 0;
  int silences = 0;  // timeouts since the oldest unanswered request changed
  Clock::time_point oldest_since = Clock::now();
  // When silence about the oldest unanswered request i sends the window again: a quarter of the timeout, doubled by
  // each silence since i became the oldest, after its latest copy's answer is due on the line model or after i
  // became the oldest (a held request's answer follows the filler's), whichever is later, and never after the
  // timeout. The slow types (EEPROM writes) wait their own time.
  auto deadline = [&](size_t i) {
    if (ws[i].type == RBX1_MSG_CONFIG_SET || ws[i].type == RBX1_MSG_CONFIG_RESET)
      return sent_at[i] + std::chrono::milliseconds(std::max(timeout_ms_.load(), 1000));
    const auto late = sent_at[i] + std::chrono::milliseconds(timeout_ms_.load());
    if (baud_ <= 0) return late;
    const auto margin = std::chrono::microseconds(timeout_ms_.load() * 250LL << std::min(silences, 8));
    return std::min(late, std::max(due[i], oldest_since) + margin);
  };
  while (base < n) {
    if (size_t k = room(); k > 0) {
      std::vector<size_t> fresh;
      for (; k > 0; --k, ++next) {
        fresh.push_back(next);
        waiting_.push_back(&ws[next]);
      }
      if (int r = send(fresh, false, lock); r < 0) {
        result = r;
        break;
      }
    }
    const auto until = deadline(base);
    auto pending = [&] {
      for (size_t i = base; i < next; ++i)
        if (!ws[i].done && (ws[i].resend || ws[i].nak)) return true;
      return false;
    };
    state_cv_.wait_until(lock, until, [&] { return ws[base].done || pending() || !connected_ || room() > 0; });
    while (base < next && ws[base].done) {
      waiting_.erase(std::find(waiting_.begin(), waiting_.end(), &ws[base]));
      last_done_ = Clock::now();
      counters_.requests++;
      ++base;
      tries = silences = 0;
      oldest_since = last_done_;
    }
    if (base == next) seen_tx_ = tx;  // every request written is answered: what was left on the line no longer counts
    if (!connected_) {
      result = down_error();
      break;
    }
    if (base == n) break;
    // The reader flagged every request an answer or NAK showed to have lost its latest copy (Link::attribute).
    std::vector<size_t> again;
    for (size_t i = base; i < next && !result; ++i) {
      if (ws[i].done) continue;
      if (ws[i].nak && ws[i].nak_reason == RBX1_SEQ_OLD) result = -EPROTO;
      if (ws[i].nak && ws[i].nak_reason == RBX1_UNKNOWN_TYPE && rbx1_request_len(ws[i].type) < 0)
        result = -EOPNOTSUPP;
      ws[i].nak = false;
      if (ws[i].resend) again.push_back(i);
    }
    if (result) break;
    // (base == next: the window moved on and the next requests are not written yet)
    bool timed_out = again.empty() && base < next && Clock::now() >= deadline(base);
    if (timed_out) {  // silence: every unanswered request again, oldest first
      counters_.timeouts++;
      ++silences;
      for (size_t i = base; i < next; ++i)
        if (!ws[i].done) again.push_back(i);
    }
    if (again.empty()) continue;
    if (again.front() == base && ++tries > retries_) {
      result = -ETIMEDOUT;
      counters_.link_down++;
      spdlog::warn("{}: link down: type 0x{:02x} seq {} unanswered after {} retransmissions", name_, ws[base].type,
                   ws[base].seq, retries_.load());
      break;
    }
    counters_.retransmissions += again.size();
    spdlog::debug("{}: resending {} frames from seq {} ({})", name_, again.size(), ws[again.front()].seq,
                  timed_out ? "timeout" : "lost copies");
    if (int r = send(again, true, lock); r < 0) {
      result = r;
      break;
    }
  }
  waiting_.clear();
  probes_.clear();
  // Unanswered SEQs (after an unknown type: every later one) would be gaps in the firmware's order.
  if (result == -ETIMEDOUT || result == -EPROTO || result == -EOPNOTSUPP) resync_ = true;
  for (size_t i = 0; i < n; ++i) {
    reqs[i].answered = ws[i].done;
    reqs[i].resp_len = ws[i].len;
    std::memcpy(reqs[i].resp, ws[i].payload, ws[i].len);
  }
  return result;
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

template <typename Resp>
int Link::typed(uint8_t type, const uint8_t* payload, uint8_t len, Resp& out,
                uint8_t (*unpack)(Resp*, const uint8_t*, uint8_t)) {
  uint8_t resp[RBX1_MAX_PAYLOAD];
  uint8_t resp_len = 0;
  int r = request(type, payload, len, resp, resp_len);
  if (r < 0) return r;
  out = Resp{};
  if (unpack(&out, resp, resp_len) == RBX1_OK) return 0;
  // A refusal may carry the status alone; an OK of the wrong length is a protocol error.
  if (resp_len >= 1 && resp[0] != RBX1_OK) {
    out.status = resp[0];
    return 0;
  }
  spdlog::error("{}: response to type 0x{:02x} has {} payload bytes", name_, type, resp_len);
  return -EBADMSG;
}

int Link::hello(rbx1_hello_resp& out) {
  rbx1_hello_req req{RBX1_PROTO_VERSION};
  uint8_t p[RBX1_HELLO_REQ_LEN];
  uint8_t n = rbx1_hello_req_pack(&req, p);
  int r = typed(RBX1_MSG_HELLO, p, n, out, rbx1_hello_resp_unpack);
  if (r < 0) return r;
  if (out.status == RBX1_BAD_VERSION || out.proto_version != RBX1_PROTO_VERSION) {
    spdlog::error("{}: protocol version mismatch: firmware {}, host {}", name_, out.proto_version,
                  RBX1_PROTO_VERSION);
    return -EPROTO;
  }
  if (out.status == RBX1_OK) {  // a new session: the order continues after the HELLO's own SEQ (next_seq_)
    std::lock_guard<std::mutex> lock(state_mu_);
    hello_ = out;
    resync_ = false;
  }
  return 0;
}

int Link::status(rbx1_status_resp& out) { return typed(RBX1_MSG_STATUS, nullptr, 0, out, rbx1_status_resp_unpack); }

int Link::heartbeat(rbx1_heartbeat_resp& out) {
  return typed(RBX1_MSG_HEARTBEAT, nullptr, 0, out, rbx1_heartbeat_resp_unpack);
}

int Link::move(const rbx1_move_req& req, rbx1_move_resp& out) {
  uint8_t p[RBX1_MOVE_REQ_LEN];
  uint8_t n = rbx1_move_req_pack(&req, p);
  return typed(RBX1_MSG_MOVE, p, n, out, rbx1_move_resp_unpack);
}

int Link::gripper(const rbx1_gripper_req& req, rbx1_gripper_resp& out) {
  uint8_t p[RBX1_GRIPPER_REQ_LEN];
  uint8_t n = rbx1_gripper_req_pack(&req, p);
  return typed(RBX1_MSG_GRIPPER, p, n, out, rbx1_gripper_resp_unpack);
}

int Link::home(uint8_t joint_mask, rbx1_home_resp& out) {
  rbx1_home_req req{joint_mask};
  uint8_t p[RBX1_HOME_REQ_LEN];
  uint8_t n = rbx1_home_req_pack(&req, p);
  return typed(RBX1_MSG_HOME, p, n, out, rbx1_home_resp_unpack);
}

int Link::stop(rbx1_stop_resp& out) { return typed(RBX1_MSG_STOP, nullptr, 0, out, rbx1_stop_resp_unpack); }

int Link::clear_fault(rbx1_clear_fault_resp& out) {
  return typed(RBX1_MSG_CLEAR_FAULT, nullptr, 0, out, rbx1_clear_fault_resp_unpack);
}

int Link::enable(bool on, rbx1_enable_resp& out) {
  rbx1_enable_req req{static_cast<uint8_t>(on ? 1 : 0)};
  uint8_t p[RBX1_ENABLE_REQ_LEN];
  uint8_t n = rbx1_enable_req_pack(&req, p);
  return typed(RBX1_MSG_ENABLE, p, n, out, rbx1_enable_resp_unpack);
}

int Link::set_position(const int32_t position[RBX1_JOINTS], rbx1_set_position_resp& out) {
  rbx1_set_position_req req{};
  std::memcpy(req.position, position, sizeof req.position);
  uint8_t p[RBX1_SET_POSITION_REQ_LEN];
  uint8_t n = rbx1_set_position_req_pack(&req, p);
  return typed(RBX1_MSG_SET_POSITION, p, n, out, rbx1_set_position_resp_unpack);
}

int Link::config_get(uint8_t joint, uint8_t key, rbx1_config_get_resp& out) {
  rbx1_config_get_req req{joint, key};
  uint8_t p[RBX1_CONFIG_GET_REQ_LEN];
  uint8_t n = rbx1_config_get_req_pack(&req, p);
  return typed(RBX1_MSG_CONFIG_GET, p, n, out, rbx1_config_get_resp_unpack);
}

int Link::config_set(uint8_t joint, uint8_t key, int32_t value, rbx1_config_set_resp& out) {
  rbx1_config_set_req req{joint, key, value};
  uint8_t p[RBX1_CONFIG_SET_REQ_LEN];
  uint8_t n = rbx1_config_set_req_pack(&req, p);
  return typed(RBX1_MSG_CONFIG_SET, p, n, out, rbx1_config_set_resp_unpack);
}

int Link::config_reset(rbx1_config_reset_resp& out) {
  return typed(RBX1_MSG_CONFIG_RESET, nullptr, 0, out, rbx1_config_reset_resp_unpack);
}

int Link::estop(rbx1_estop_resp& out) {
  // Not request_mu_: the frame must not wait behind an outstanding request.
  std::lock_guard<std::mutex> lock(estop_mu_);
  Waiter w;
  w.type = RBX1_MSG_ESTOP;
  {
    std::lock_guard<std::mutex> state(state_mu_);
    if (!connected_) return down_error();
    w.seq = next_seq_;  // outside the window: the SEQ is echoed, not consumed (the next request still uses it)
  }
  uint8_t frame[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(frame, sizeof frame, w.seq, RBX1_MSG_ESTOP, nullptr, 0);
  uint8_t resp[RBX1_MAX_PAYLOAD];
  uint8_t resp_len = 0;
  spdlog::warn("{}: ESTOP (seq {})", name_, w.seq);
  int r = transact(w, true, frame, n, resp, resp_len);
  if (r < 0) return r;
  out = rbx1_estop_resp{};
  if (rbx1_estop_resp_unpack(&out, resp, resp_len) != RBX1_OK) {
    if (resp_len < 1) return -EBADMSG;
    out.status = resp[0];
  }
  return 0;
}

int Link::estop() {
  rbx1_estop_resp out{};
  return estop(out);
}

int Link::heartbeat_if_due(int heartbeat_ms) {
  {
    std::lock_guard<std::mutex> lock(state_mu_);
    if (Clock::now() - last_done_ < std::chrono::milliseconds(heartbeat_ms)) return 0;
  }
  rbx1_heartbeat_resp out{};
  return heartbeat(out);
}

void Link::start_heartbeat(int period_ms) {
  stop_heartbeat();
  hb_stop_ = false;
  hb_thread_ = std::thread([this, period_ms] {
    std::unique_lock<std::mutex> lock(hb_mu_);
    while (!hb_cv_.wait_for(lock, std::chrono::milliseconds(std::max(period_ms / 4, 5)), [&] { return hb_stop_; })) {
      if (!connected_) continue;
      lock.unlock();
      int r = heartbeat_if_due(period_ms);
      if (r < 0) spdlog::debug("{}: heartbeat failed: {}", name_, std::strerror(-r));
      lock.lock();
    }
  });
}

void Link::stop_heartbeat() {
  {
    std::lock_guard<std::mutex> lock(hb_mu_);
    hb_stop_ = true;
  }
  hb_cv_.notify_all();
  if (hb_thread_.joinable()) hb_thread_.join();
}

LinkStats Link::stats() const {
  LinkStats s;
  s.requests = counters_.requests;
  s.retransmissions = counters_.retransmissions;
  s.timeouts = counters_.timeouts;
  s.naks = counters_.naks;
  s.stale = counters_.stale;
  s.rejected = counters_.rejected;
  s.link_down = counters_.link_down;
  s.reconnects = counters_.reconnects;
  s.bytes_sent = counters_.bytes_sent;
  s.bytes_received = counters_.bytes_received;
  s.probes = counters_.probes;
  return s;
}

rbx1_hello_resp Link::firmware() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  return hello_;
}

uint8_t Link::next_seq() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  return next_seq_;
}

}  // namespace rbx1::link
