// fake_peer.cpp - the scripted firmware of the link tests: decoder, the window (rbx1_window), fault injection.
#include "fake_peer.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <poll.h>
#include <pty.h>
#include <unistd.h>

namespace rbx1::link::test {

using Clock = std::chrono::steady_clock;

FakePeer::FakePeer() {
  int slave = -1;
  char name[128];
  if (openpty(&master_, &slave, name, nullptr, nullptr) != 0) throw std::runtime_error("openpty failed");
  slave_ = name;
  ::close(slave);  // the link under test opens it by path
  rbx1_decoder_init(&decoder_, &FakePeer::on_frame, nullptr, this);
  thread_ = std::thread(&FakePeer::loop, this);
}

FakePeer::~FakePeer() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (master_ >= 0) ::close(master_);
}

void FakePeer::hang_up() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  ::close(master_);
  master_ = -1;
}

std::vector<FakePeer::Received> FakePeer::received() const {
  std::lock_guard<std::mutex> lock(mu_);
  return received_;
}

int FakePeer::executed(uint8_t type) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = executed_.find(type);
  return it == executed_.end() ? 0 : it->second;
}

Clock::time_point FakePeer::sent_at(uint8_t type) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sent_at_.find(type);
  return it == sent_at_.end() ? Clock::time_point{} : it->second;
}

void FakePeer::loop() {
  uint8_t buf[256];
  while (!stop_) {
    pollfd p{master_, POLLIN, 0};
    int n = poll(&p, 1, 2);
    if (n > 0 && (p.revents & POLLIN)) {
      ssize_t got = ::read(master_, buf, sizeof buf);
      if (got > 0) rbx1_decoder_feed(&decoder_, buf, static_cast<size_t>(got));
    } else if (n > 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // no slave open (EIO/HUP): wait for one
    }
    std::vector<Pending> due;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto now = Clock::now();
      for (auto it = pending_.begin(); it != pending_.end();) {
        if (it->due <= now) {
          due.push_back(*it);
          it = pending_.erase(it);
        } else {
          ++it;
        }
      }
    }
    for (auto& d : due) send(d.bytes, d.type);
  }
}

void FakePeer::on_frame(void* ctx, const rbx1_frame* f) { static_cast<FakePeer*>(ctx)->handle(*f); }

void FakePeer::handle(const rbx1_frame& f) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    received_.push_back({f.seq, f.type, f.crc, Clock::now()});
  }
  const bool request = rbx1_request_len(f.type) >= 0;
  if (request && drop_next > 0) {
    --drop_next;
    return;
  }
  if (request && f.seq == drop_seq && drop_seq_times > 0) {
    --drop_seq_times;
    return;
  }
  if (!request && drop_probes > 0) {
    --drop_probes;
    return;
  }
  if (silence_after_type < 0) silence_left_ = -1;
  if (silence_left_ == 0) return;
  if (nak_next > 0) {
    --nak_next;
    rbx1_nak nak{nak_reason};
    uint8_t p[RBX1_NAK_LEN];
    uint8_t n = rbx1_nak_pack(&nak, p);
    respond(f.seq, RBX1_MSG_NAK, p, n, false);
    return;
  }
  // The window, as in the firmware: duplicates answered from memory, requests ahead of a gap held, further gaps and
  // old frames NAKed, ESTOP outside (it drops the held requests).
  const rbx1_window_entry* dup = nullptr;
  uint8_t before_hello = 0xFF;
  uint8_t verdict = rbx1_window_accept(&window_, &f, &dup, &before_hello);
  bool corrupt = false;  // only responses count for corrupt_next (not NAKs)
  if ((verdict == RBX1_WIN_DUPLICATE || verdict == RBX1_WIN_NEW || verdict == RBX1_WIN_BYPASS) && corrupt_next > 0) {
    --corrupt_next;
    corrupt = true;
  }
  if (verdict == RBX1_WIN_DUPLICATE) {
    ++cached_replies_;
    respond(f.seq, dup->type, dup->payload, dup->len, corrupt);
    return;
  }
  if (verdict == RBX1_WIN_UNKNOWN) {  // as the firmware: NAKed, not executed, no place in the order
    ++unknown_;
    rbx1_nak nak{RBX1_UNKNOWN_TYPE};
    uint8_t p[RBX1_NAK_LEN];
    respond(f.seq, RBX1_MSG_NAK, p, rbx1_nak_pack(&nak, p), false);
    return;
  }
  if (verdict == RBX1_WIN_HELD) {
    ++held_;
    rbx1_nak nak{RBX1_HELD};
    uint8_t p[RBX1_NAK_LEN];
    respond(f.seq, RBX1_MSG_NAK, p, rbx1_nak_pack(&nak, p), false);
    return;
  }
  if (verdict == RBX1_WIN_GAP || verdict == RBX1_WIN_OLD) {
    ++refused_;
    rbx1_nak nak{verdict == RBX1_WIN_GAP ? uint8_t(RBX1_SEQ_GAP) : uint8_t(RBX1_SEQ_OLD)};
    uint8_t p[RBX1_NAK_LEN];
    respond(f.seq, RBX1_MSG_NAK, p, rbx1_nak_pack(&nak, p), false);
    return;
  }
  if (f.type == RBX1_MSG_HELLO && before_hello != 0xFF) last_seq = before_hello;
  if (silence_left_ > 0) --silence_left_;  // counts new requests; a retransmission above is answered again
  uint8_t resp[RBX1_MAX_PAYLOAD];
  uint8_t len = execute(f, resp);
  if (verdict == RBX1_WIN_NEW) rbx1_window_record(&window_, f.seq, f.crc, RBX1_RESPONSE(f.type), resp, len);
  if (stale_first) {
    uint8_t other[RBX1_MAX_PAYLOAD];
    std::memcpy(other, resp, len);
    respond(static_cast<uint8_t>(f.seq - 1), RBX1_RESPONSE(f.type), other, len, false);
  }
  respond(f.seq, RBX1_RESPONSE(f.type), resp, len, corrupt);
  if (duplicate) respond(f.seq, RBX1_RESPONSE(f.type), resp, len, false);
  if (silence_left_ < 0 && silence_after_type == f.type) silence_left_ = silence_after_count;
  if (verdict == RBX1_WIN_BYPASS) {  // ESTOP: the held requests are dropped, never run, each NAKed SEQ_GAP
    uint8_t seqs[RBX1_HELD_MAX];
    for (uint8_t i = 0, n = rbx1_window_drop_held(&window_, seqs); i < n; ++i) {
      rbx1_nak nak{RBX1_SEQ_GAP};
      uint8_t p[RBX1_NAK_LEN];
      respond(seqs[i], RBX1_MSG_NAK, p, rbx1_nak_pack(&nak, p), false);
    }
  }
  // A filled gap: the requests held behind it run now, in SEQ order.
  for (const rbx1_window_held* h; verdict == RBX1_WIN_NEW && (h = rbx1_window_release(&window_)) != nullptr;) {
    rbx1_frame g{};
    g.seq = h->seq;
    g.type = h->type;
    g.len = h->len;
    g.crc = h->crc;
    std::memcpy(g.payload, h->payload, std::min<size_t>(h->len, RBX1_MAX_REQ_LEN));
    uint8_t out[RBX1_MAX_PAYLOAD];
    uint8_t n = execute(g, out);
    rbx1_window_record(&window_, g.seq, g.crc, RBX1_RESPONSE(g.type), out, n);
    respond(g.seq, RBX1_RESPONSE(g.type), out, n, false);
  }
}

// A tiny firmware: every request succeeds; MOVE and GRIPPER count as done at once.
uint8_t FakePeer::execute(const rbx1_frame& f, uint8_t* resp) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++executed_[f.type];
  }
  switch (f.type) {
    case RBX1_MSG_HELLO: {
      rbx1_hello_resp h{};
      h.proto_version = proto_version;
      h.status = h.proto_version == RBX1_PROTO_VERSION ? RBX1_OK : RBX1_BAD_VERSION;
      h.fw_major = 0;
      h.fw_minor = 9;
      h.fw_patch = 1;
      h.joints = RBX1_JOINTS;
      h.queue_size = 8;
      h.capabilities = 0x10;
      h.last_seq = last_seq;
      h.window = window_size;
      return rbx1_hello_resp_pack(&h, resp);
    }
    case RBX1_MSG_STATUS: {
      rbx1_status_resp s{};
      s.moves_done = moves_done_;
      s.moves_accepted = moves_done_;  // every entry completes at once
      s.homed = homed_;
      s.enabled = enabled_;
      s.queue_free = 8;
      for (int j = 0; j < RBX1_JOINTS; ++j) s.position[j] = j * 1000 - 2500;
      return rbx1_status_resp_pack(&s, resp);
    }
    case RBX1_MSG_MOVE:
    case RBX1_MSG_GRIPPER: {
      ++moves_done_;
      rbx1_move_req q{};
      if (f.type == RBX1_MSG_MOVE && rbx1_move_req_unpack(&q, f.payload, f.len) == RBX1_OK) {
        std::lock_guard<std::mutex> lock(mu_);
        move_targets_.push_back(q.target[0]);
      }
      rbx1_move_resp m{RBX1_OK, 7};
      return rbx1_move_resp_pack(&m, resp);
    }
    case RBX1_MSG_SET_POSITION:
    case RBX1_MSG_HOME:
      homed_ = RBX1_ALL_JOINTS_MASK;
      resp[0] = RBX1_OK;
      return 1;
    case RBX1_MSG_ENABLE:
      enabled_ = f.len == 1 ? f.payload[0] : enabled_;
      resp[0] = RBX1_OK;
      return 1;
    case RBX1_MSG_CONFIG_GET: {
      rbx1_config_get_req q{};
      rbx1_config_get_req_unpack(&q, f.payload, f.len);
      rbx1_config_get_resp g{RBX1_OK, q.joint * 100 + q.key};
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (auto it = config_.find(q.joint << 8 | q.key); it != config_.end()) g.value = it->second;
      }
      return rbx1_config_get_resp_pack(&g, resp);
    }
    default:
      resp[0] = RBX1_OK;
      return 1;
  }
}

void FakePeer::respond(uint8_t seq, uint8_t type, const uint8_t* payload, uint8_t len, bool corrupt) {
  uint8_t frame[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(frame, sizeof frame, seq, type, payload, len);
  // Two CRC bytes damaged: more than the parity corrects (one byte), so the frame is rejected, not repaired.
  if (corrupt) {
    frame[n - RBX1_FEC_BYTES - 1] ^= 0x5A;
    frame[n - RBX1_FEC_BYTES - 2] ^= 0x5A;
  }
  if (v4_frames) n -= RBX1_FEC_BYTES;
  std::vector<uint8_t> bytes(frame, frame + n);
  if (delay_type >= 0 && RBX1_RESPONSE(static_cast<uint8_t>(delay_type)) == type && delay_ms > 0) {
    std::lock_guard<std::mutex> lock(mu_);
    pending_.push_back({Clock::now() + std::chrono::milliseconds(delay_ms), bytes, type});
    return;
  }
  if (delay_all_ms > 0) {  // due times grow with the order of the frames: they go out in that order
    std::lock_guard<std::mutex> lock(mu_);
    pending_.push_back({Clock::now() + std::chrono::milliseconds(delay_all_ms), bytes, type});
    return;
  }
  send(bytes, type);
}

void FakePeer::send(const std::vector<uint8_t>& bytes, uint8_t type) {
  if (::write(master_, bytes.data(), bytes.size()) < 0) return;  // no slave open: the bytes are lost
  std::lock_guard<std::mutex> lock(mu_);
  sent_at_[type & 0x7F] = Clock::now();
}

}  // namespace rbx1::link::test
