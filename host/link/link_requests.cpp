// link_requests.cpp - a Link's single requests: the write lock, one request in flight with retransmission, the
// resync HELLO after a lost SEQ, the typed helpers, e-stop from any thread, heartbeat.
#include "link.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <unistd.h>

#include <spdlog/spdlog.h>

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

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

}  // namespace rbx1::link
