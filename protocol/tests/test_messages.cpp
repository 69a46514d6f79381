// test_messages.cpp - generated message pack/unpack against the shared vectors, round trips and length checks.
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <map>
#include <string>

#include "rbx1_proto.h"
#include "vectors.hpp"

using nlohmann::json;
using rbx1test::hex;
using rbx1test::load_vectors;
using rbx1test::unhex;

namespace {

// Field visitors, written by hand from messages.json so that a generator mistake (name, order, type) shows.
template <class V> void visit(rbx1_hello_req& m, V&& v) { v("proto_version", m.proto_version); }
template <class V> void visit(rbx1_hello_resp& m, V&& v) {
  v("status", m.status); v("proto_version", m.proto_version); v("fw_major", m.fw_major);
  v("fw_minor", m.fw_minor); v("fw_patch", m.fw_patch); v("joints", m.joints); v("queue_size", m.queue_size);
  v("capabilities", m.capabilities); v("last_seq", m.last_seq); v("window", m.window);
}
template <class V> void visit(rbx1_status_resp& m, V&& v) {
  v("status", m.status); v("state", m.state); v("faults", m.faults); v("homed", m.homed); v("inputs", m.inputs);
  v("enabled", m.enabled); v("queue_free", m.queue_free); v("moves_done", m.moves_done);
  v("gripper_us", m.gripper_us); v("position", m.position); v("moves_accepted", m.moves_accepted);
  v("moves_flushed", m.moves_flushed);
}
template <class V> void visit(rbx1_heartbeat_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_move_req& m, V&& v) { v("target", m.target); v("duration_ms", m.duration_ms); }
template <class V> void visit(rbx1_move_resp& m, V&& v) { v("status", m.status); v("queue_free", m.queue_free); }
template <class V> void visit(rbx1_gripper_req& m, V&& v) { v("pulse_us", m.pulse_us); v("dwell_ms", m.dwell_ms); }
template <class V> void visit(rbx1_gripper_resp& m, V&& v) { v("status", m.status); v("queue_free", m.queue_free); }
template <class V> void visit(rbx1_home_req& m, V&& v) { v("joint_mask", m.joint_mask); }
template <class V> void visit(rbx1_home_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_stop_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_estop_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_clear_fault_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_enable_req& m, V&& v) { v("enable", m.enable); }
template <class V> void visit(rbx1_enable_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_set_position_req& m, V&& v) { v("position", m.position); }
template <class V> void visit(rbx1_set_position_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_config_get_req& m, V&& v) { v("joint", m.joint); v("key", m.key); }
template <class V> void visit(rbx1_config_get_resp& m, V&& v) { v("status", m.status); v("value", m.value); }
template <class V> void visit(rbx1_config_set_req& m, V&& v) { v("joint", m.joint); v("key", m.key); v("value", m.value); }
template <class V> void visit(rbx1_config_set_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_config_reset_resp& m, V&& v) { v("status", m.status); }
template <class V> void visit(rbx1_nak& m, V&& v) { v("reason", m.reason); }

struct ToJson {
  json& j;
  template <class T> void operator()(const char* name, const T& x) { j[name] = x; }
};
struct FromJson {
  const json& j;
  template <class T> void operator()(const char* name, T& x) { x = j.at(name).get<T>(); }
  template <class T, size_t N> void operator()(const char* name, T (&x)[N]) {
    ASSERT_EQ(j.at(name).size(), N) << name;
    for (size_t i = 0; i < N; i++) x[i] = j.at(name)[i].get<T>();
  }
};

// Pack/unpack of one struct type, driven by JSON fields.
struct Codec {
  size_t expected_len;
  std::function<std::vector<uint8_t>(const json&)> pack;
  std::function<uint8_t(const std::vector<uint8_t>&, uint8_t len, json*)> unpack;  // len may differ from size
};

template <class T> Codec codec(uint8_t (*pack)(const T*, uint8_t*), uint8_t (*unpack)(T*, const uint8_t*, uint8_t),
                               size_t len) {
  Codec c;
  c.expected_len = len;
  c.pack = [pack](const json& fields) {
    T m;
    std::memset(&m, 0xCC, sizeof m);
    visit(m, FromJson{fields});
    uint8_t buf[RBX1_MAX_PAYLOAD + 8];
    std::memset(buf, 0xEE, sizeof buf);
    uint8_t n = pack(&m, buf);
    for (size_t i = n; i < sizeof buf; i++) EXPECT_EQ(buf[i], 0xEE) << "pack wrote past its length";
    return std::vector<uint8_t>(buf, buf + n);
  };
  c.unpack = [unpack](const std::vector<uint8_t>& payload, uint8_t len, json* out) {
    T m;
    std::memset(&m, 0xCC, sizeof m);
    uint8_t st = unpack(&m, payload.data(), len);
    if (st == RBX1_OK) {
      *out = json::object();
      visit(m, ToJson{*out});
    }
    return st;
  };
  return c;
}

#define REQ(NAME, name) {RBX1_MSG_##NAME, codec<rbx1_##name##_req>(rbx1_##name##_req_pack, rbx1_##name##_req_unpack, RBX1_##NAME##_REQ_LEN)}
#define RESP(NAME, name) {RBX1_MSG_##NAME, codec<rbx1_##name##_resp>(rbx1_##name##_resp_pack, rbx1_##name##_resp_unpack, RBX1_##NAME##_RESP_LEN)}

const std::map<int, Codec>& requests() {
  static const std::map<int, Codec> m = {REQ(HELLO, hello), REQ(MOVE, move), REQ(GRIPPER, gripper),
                                         REQ(HOME, home), REQ(ENABLE, enable), REQ(SET_POSITION, set_position),
                                         REQ(CONFIG_GET, config_get), REQ(CONFIG_SET, config_set)};
  return m;
}
const std::map<int, Codec>& responses() {
  static const std::map<int, Codec> m = {
      RESP(HELLO, hello), RESP(STATUS, status), RESP(HEARTBEAT, heartbeat), RESP(MOVE, move),
      RESP(GRIPPER, gripper), RESP(HOME, home), RESP(STOP, stop), RESP(ESTOP, estop),
      RESP(CLEAR_FAULT, clear_fault), RESP(ENABLE, enable), RESP(SET_POSITION, set_position),
      RESP(CONFIG_GET, config_get), RESP(CONFIG_SET, config_set), RESP(CONFIG_RESET, config_reset)};
  return m;
}
const Codec& nak_codec() {
  static const Codec c = codec<rbx1_nak>(rbx1_nak_pack, rbx1_nak_unpack, RBX1_NAK_LEN);
  return c;
}

// The codec for a vector, or nullptr for an empty request payload (no struct exists for it).
const Codec* codec_for(const json& v) {
  const std::string kind = v["kind"];
  const int msg = v["msg"];
  if (kind == "nak") return &nak_codec();
  const auto& table = kind == "request" ? requests() : responses();
  auto it = table.find(msg);
  return it == table.end() ? nullptr : &it->second;
}

struct Capture {
  std::vector<rbx1_frame> frames;
  static void on_frame(void* ctx, const rbx1_frame* f) { static_cast<Capture*>(ctx)->frames.push_back(*f); }
};

}  // namespace

TEST(Messages, VectorsPackAndUnpack) {
  const json vs = load_vectors("messages.json");
  int checked = 0;
  for (const auto& v : vs) {
    auto payload = unhex(v["payload"]);
    const Codec* c = codec_for(v);
    if (!c) {  // empty request payload
      EXPECT_TRUE(payload.empty()) << v["name"];
      EXPECT_EQ(rbx1_request_len(v["msg"].get<uint8_t>()), 0) << v["name"];
      continue;
    }
    EXPECT_EQ(payload.size(), c->expected_len) << v["name"];
    EXPECT_EQ(c->pack(v["fields"]), payload) << v["name"];
    json fields;
    ASSERT_EQ(c->unpack(payload, static_cast<uint8_t>(payload.size()), &fields), RBX1_OK) << v["name"];
    EXPECT_EQ(fields, v["fields"]) << v["name"];
    checked++;
  }
  EXPECT_EQ(checked, 8 + 14 + 3);
}

TEST(Messages, RoundTripEveryTypeThroughTheWire) {
  // fields -> pack -> frame -> decoder -> unpack -> the same fields, for every request and response type.
  int round_trips = 0;
  for (const auto& v : load_vectors("messages.json")) {
    const Codec* c = codec_for(v);
    std::vector<uint8_t> payload = c ? c->pack(v["fields"]) : std::vector<uint8_t>{};
    uint8_t wire[RBX1_MAX_FRAME];
    size_t n = rbx1_frame_encode(wire, sizeof wire, v["seq"].get<uint8_t>(), v["type"].get<uint8_t>(), payload.data(),
                                 static_cast<uint8_t>(payload.size()));
    ASSERT_EQ(n, payload.size() + RBX1_FRAME_OVERHEAD);
    Capture cap;
    rbx1_decoder d;
    rbx1_decoder_init(&d, Capture::on_frame, nullptr, &cap);
    rbx1_decoder_feed(&d, wire, n);
    ASSERT_EQ(cap.frames.size(), 1u) << v["name"];
    const rbx1_frame& f = cap.frames[0];
    EXPECT_EQ(f.type, v["type"].get<int>());
    EXPECT_EQ(f.seq, v["seq"].get<int>());
    if (v["kind"] == "request") {
      EXPECT_EQ(rbx1_request_len(f.type), f.len) << v["name"];
    } else if (v["kind"] == "response") {
      EXPECT_EQ(rbx1_response_len(f.type & 0x7F), f.len) << v["name"];
    }
    if (c) {
      json back;
      ASSERT_EQ(c->unpack(std::vector<uint8_t>(f.payload, f.payload + f.len), f.len, &back), RBX1_OK);
      EXPECT_EQ(back, v["fields"]) << v["name"];
    } else {
      EXPECT_EQ(f.len, 0);
    }
    round_trips++;
  }
  EXPECT_EQ(round_trips, 31);
}

TEST(Messages, UnpackRejectsEveryWrongLength) {
  std::vector<const Codec*> all;
  for (const auto& [t, c] : requests()) all.push_back(&c);
  for (const auto& [t, c] : responses()) all.push_back(&c);
  all.push_back(&nak_codec());
  for (const Codec* c : all) {
    std::vector<uint8_t> buf(RBX1_MAX_PAYLOAD + 2, 0x5A);
    for (int len = 0; len <= RBX1_MAX_PAYLOAD + 1; len++) {
      json out;
      uint8_t st = c->unpack(buf, static_cast<uint8_t>(len), &out);
      EXPECT_EQ(st, size_t(len) == c->expected_len ? RBX1_OK : RBX1_BAD_LENGTH) << len;
    }
  }
}

TEST(Messages, LengthsMatchTheContract) {
  EXPECT_EQ(RBX1_MOVE_REQ_LEN, 26);
  EXPECT_EQ(RBX1_MOVE_RESP_LEN, 2);
  EXPECT_EQ(RBX1_STATUS_RESP_LEN, 40);
  EXPECT_EQ(RBX1_HELLO_RESP_LEN, 11);
  EXPECT_EQ(rbx1_request_len(RBX1_MSG_MOVE), 26);
  EXPECT_EQ(rbx1_request_len(RBX1_MSG_STATUS), 0);
  EXPECT_EQ(rbx1_request_len(RBX1_MSG_CONFIG_SET), 6);
  EXPECT_EQ(rbx1_request_len(RBX1_MSG_NAK), -1);
  EXPECT_EQ(rbx1_request_len(0x00), -1);
  EXPECT_EQ(rbx1_request_len(0x0F), -1);
  EXPECT_EQ(rbx1_request_len(RBX1_RESPONSE(RBX1_MSG_MOVE)), -1);
  EXPECT_EQ(rbx1_response_len(RBX1_MSG_STATUS), 40);
  int known = 0;
  for (int t = 0; t < 256; t++) known += rbx1_request_len(static_cast<uint8_t>(t)) >= 0;
  EXPECT_EQ(known, 14);
}

TEST(Messages, CodesAndBits) {
  EXPECT_EQ(RBX1_MSG_HELLO, 0x01);
  EXPECT_EQ(RBX1_MSG_CONFIG_RESET, 0x0E);
  EXPECT_EQ(RBX1_MSG_NAK, 0x7F);
  EXPECT_EQ(RBX1_OK, 0);
  EXPECT_EQ(RBX1_EEPROM_ERROR, 13);
  EXPECT_EQ(RBX1_STATE_FAULT, 4);
  EXPECT_EQ(RBX1_FAULT_ESTOP_INPUT, 1u << 0);
  EXPECT_EQ(RBX1_FAULT_EEPROM_DEFAULTS, 1u << 6);
  EXPECT_EQ(RBX1_FAULTS_LATCHING, 0x1Fu);
  EXPECT_EQ(RBX1_INPUT_LIMIT_J6, 1u << 5);
  EXPECT_EQ(RBX1_INPUT_ESTOP, 1u << 6);
  EXPECT_EQ(RBX1_CAP_SIMULATED, 1u << 4);
  EXPECT_EQ(RBX1_GLOBAL_JOINT, 0xFFu);
  EXPECT_STREQ(rbx1_status_name(RBX1_OK), "OK");
  EXPECT_STREQ(rbx1_status_name(RBX1_QUEUE_FULL), "QUEUE_FULL");
  EXPECT_STREQ(rbx1_status_name(200), "?");
}

TEST(Messages, KeyTable) {
  const rbx1_key_info* k = rbx1_key_lookup(RBX1_KEY_MAX_SPEED);
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->key, 3);
  EXPECT_EQ(k->is_global, 0);
  EXPECT_EQ(k->min, 1);
  EXPECT_EQ(k->max, 20000);
  EXPECT_EQ(k->default_value, 4000);
  k = rbx1_key_lookup(RBX1_KEY_HEARTBEAT_MS);
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->is_global, 1);
  EXPECT_EQ(k->min, 100);
  EXPECT_EQ(k->max, 60000);
  k = rbx1_key_lookup(RBX1_KEY_SOFT_MIN);
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->min, -2147483647);
  EXPECT_EQ(k->default_value, -100000);
  int found = 0;
  for (int key = 0; key < 256; key++) found += rbx1_key_lookup(static_cast<uint8_t>(key)) != nullptr;
  EXPECT_EQ(found, RBX1_KEY_COUNT);
  EXPECT_EQ(found, 11);
  EXPECT_EQ(rbx1_key_lookup(0), nullptr);
  EXPECT_EQ(rbx1_key_lookup(9), nullptr);
}

TEST(Messages, BadPayloadVectorsAreRefused) {
  const json vs = load_vectors("bad_payloads.json");
  ASSERT_GE(vs.size(), 50u);
  int refused = 0;
  for (const auto& v : vs) {
    auto payload = unhex(v["payload"]);
    const int msg = v["msg"];
    const auto& table = v["kind"] == "request" ? requests() : responses();
    auto it = table.find(msg);
    if (it == table.end()) {  // empty request payload: no struct; the length alone says it is wrong
      EXPECT_NE(payload.size(), size_t(rbx1_request_len(static_cast<uint8_t>(msg)))) << v["name"];
      continue;
    }
    json out;
    payload.resize(RBX1_MAX_PAYLOAD + 2, 0);  // room to read past len if unpack ignored it
    EXPECT_EQ(it->second.unpack(payload, static_cast<uint8_t>(unhex(v["payload"]).size()), &out), RBX1_BAD_LENGTH)
        << v["name"];
    refused++;
  }
  EXPECT_GT(refused, 40);
}
