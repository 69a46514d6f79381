// fw_fixture.hpp - GoogleTest fixture: the firmware core on the simulated board with a simulated host that sends
// framed requests and decodes the responses; time advances only when a test says so.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "firmware.h"
#include "hal_sim.hpp"
#include "rbx1_proto.h"

namespace rbx1::fwtest {

struct Reply {
  bool got = false;
  uint8_t seq = 0, type = 0;
  std::vector<uint8_t> payload;
};

class Fw : public ::testing::Test {
 public:  // helpers are public so that free check functions can drive a test's firmware
  void SetUp() override {
    sim::board() = sim::Board{};
    sim::erase_eeprom();
    boot();
  }
  void TearDown() override {
    sim::board().on_step = nullptr;
    sim::board().on_entry_done = nullptr;
  }

  // Power cycle (EEPROM kept) and firmware setup.
  void boot() {
    sim::power_on();
    fw_setup();
    frames_.clear();
    rbx1_decoder_init(&dec_, &Fw::on_frame, &Fw::on_reject, this);
  }

  // Advances simulated time by ms, running the main loop every 0.25 ms as the AVR would (much more often).
  void run_ms(uint32_t ms, bool heartbeat = false) {
    for (uint32_t i = 0; i < ms * 4; i++) {
      sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
      fw_loop();
      if (heartbeat && i % 800 == 799) request(RBX1_MSG_HEARTBEAT, nullptr, 0);
    }
    collect();
  }

  // Runs until the firmware is IDLE (or FAULT), polling STATUS (which is also the heartbeat) every 10 ms, at
  // most max_ms. Returns the simulated ms it took (to 10 ms).
  uint32_t run_until_idle(uint32_t max_ms = 60000) {
    uint64_t t0 = sim::board().now;
    for (uint32_t t = 0; t < max_ms; t += 10) {
      run_ms(10);
      rbx1_status_resp s = status();
      if (s.state == RBX1_STATE_IDLE || s.state == RBX1_STATE_FAULT)
        return (uint32_t)((sim::board().now - t0) / sim::kTicksPerMs);
    }
    ADD_FAILURE() << "not idle after " << max_ms << " ms";
    return max_ms;
  }

  // Raw bytes into the firmware's receive queue.
  void send_bytes(const uint8_t* p, size_t n) { sim::board().rx.insert(sim::board().rx.end(), p, p + n); }
  std::vector<uint8_t> encode(uint8_t seq, uint8_t type, const uint8_t* payload, uint8_t len) {
    std::vector<uint8_t> f(RBX1_MAX_FRAME);
    f.resize(rbx1_frame_encode(f.data(), f.size(), seq, type, payload, len));
    return f;
  }

  // Sends bytes (frames, garbage) at once and runs ms of simulated time: frames_ then holds every answer, in order.
  void send_run(const std::vector<uint8_t>& bytes, uint32_t ms = 5) {
    frames_.clear();
    send_bytes(bytes.data(), bytes.size());
    run_ms(ms);
  }

  // Sends bytes and returns the first reply (response or NAK) within 20 ms, if any.
  Reply exchange(const std::vector<uint8_t>& frame) {
    frames_.clear();
    send_bytes(frame.data(), frame.size());
    for (int i = 0; i < 80 && frames_.empty(); i++) {
      sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
      fw_loop();
      collect();
    }
    return frames_.empty() ? Reply{} : frames_.front();
  }

  // The next SEQ in order; ESTOP takes no place in the order (PROTOCOL.md "Window"), so it does not consume one.
  Reply request(uint8_t type, const uint8_t* payload, uint8_t len) {
    return exchange(encode(type == RBX1_MSG_ESTOP ? seq_ : seq_++, type, payload, len));
  }
  // The next in-order SEQ, consumed (for tests that build their own frames).
  uint8_t take_seq() { return seq_++; }

  // Typed helpers: return the response's status (and fill the struct).
  rbx1_status_resp status() {
    rbx1_status_resp s{};
    Reply r = request(RBX1_MSG_STATUS, nullptr, 0);
    EXPECT_TRUE(r.got);
    EXPECT_EQ(rbx1_status_resp_unpack(&s, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
    return s;
  }
  uint8_t simple(uint8_t type, const uint8_t* payload = nullptr, uint8_t len = 0) {
    Reply r = request(type, payload, len);
    EXPECT_TRUE(r.got);
    EXPECT_EQ(r.type, RBX1_RESPONSE(type));
    return r.payload.empty() ? 0xFF : r.payload[0];
  }
  uint8_t enable(uint8_t on) {
    rbx1_enable_req q{on};
    uint8_t p[RBX1_ENABLE_REQ_LEN];
    return simple(RBX1_MSG_ENABLE, p, rbx1_enable_req_pack(&q, p));
  }
  uint8_t set_position(std::vector<int32_t> pos) {
    rbx1_set_position_req q{};
    std::memcpy(q.position, pos.data(), sizeof(q.position));
    uint8_t p[RBX1_SET_POSITION_REQ_LEN];
    return simple(RBX1_MSG_SET_POSITION, p, rbx1_set_position_req_pack(&q, p));
  }
  uint8_t move(std::vector<int32_t> target, uint16_t duration_ms = 0, uint8_t* queue_free = nullptr) {
    rbx1_move_req q{};
    std::memcpy(q.target, target.data(), sizeof(q.target));
    q.duration_ms = duration_ms;
    uint8_t p[RBX1_MOVE_REQ_LEN];
    Reply r = request(RBX1_MSG_MOVE, p, rbx1_move_req_pack(&q, p));
    rbx1_move_resp m{};
    EXPECT_EQ(rbx1_move_resp_unpack(&m, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
    if (queue_free) *queue_free = m.queue_free;
    return m.status;
  }
  uint8_t gripper(uint16_t pulse, uint16_t dwell, uint8_t* queue_free = nullptr) {
    rbx1_gripper_req q{pulse, dwell};
    uint8_t p[RBX1_GRIPPER_REQ_LEN];
    Reply r = request(RBX1_MSG_GRIPPER, p, rbx1_gripper_req_pack(&q, p));
    rbx1_gripper_resp m{};
    EXPECT_EQ(rbx1_gripper_resp_unpack(&m, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
    if (queue_free) *queue_free = m.queue_free;
    return m.status;
  }
  uint8_t config_set(uint8_t joint, uint8_t key, int32_t value) {
    rbx1_config_set_req q{joint, key, value};
    uint8_t p[RBX1_CONFIG_SET_REQ_LEN];
    return simple(RBX1_MSG_CONFIG_SET, p, rbx1_config_set_req_pack(&q, p));
  }
  uint8_t config_get(uint8_t joint, uint8_t key, int32_t* value) {
    rbx1_config_get_req q{joint, key};
    uint8_t p[RBX1_CONFIG_GET_REQ_LEN];
    Reply r = request(RBX1_MSG_CONFIG_GET, p, rbx1_config_get_req_pack(&q, p));
    rbx1_config_get_resp m{};
    EXPECT_EQ(rbx1_config_get_resp_unpack(&m, r.payload.data(), (uint8_t)r.payload.size()), RBX1_OK);
    *value = m.value;
    return m.status;
  }
  uint8_t home(uint8_t mask) {
    rbx1_home_req q{mask};
    uint8_t p[RBX1_HOME_REQ_LEN];
    return simple(RBX1_MSG_HOME, p, rbx1_home_req_pack(&q, p));
  }
  // Enabled, positions declared at 0: ready for moves.
  void ready() {
    ASSERT_EQ(enable(1), RBX1_OK);
    ASSERT_EQ(set_position({0, 0, 0, 0, 0, 0}), RBX1_OK);
  }

  // Decodes what the firmware sent into frames_.
  void collect() {
    auto& tx = sim::board().tx;
    if (!tx.empty()) rbx1_decoder_feed(&dec_, tx.data(), tx.size());
    tx.clear();
  }

  std::vector<Reply> frames_;
  uint8_t seq_ = 0;

 private:
  static void on_frame(void* ctx, const rbx1_frame* f) {
    Reply r;
    r.got = true;
    r.seq = f->seq;
    r.type = f->type;
    r.payload.assign(f->payload, f->payload + f->len);
    static_cast<Fw*>(ctx)->frames_.push_back(r);
  }
  static void on_reject(void*, uint8_t, uint8_t, uint8_t) { ADD_FAILURE() << "firmware sent a corrupt frame"; }
  rbx1_decoder dec_{};
};

}  // namespace rbx1::fwtest
