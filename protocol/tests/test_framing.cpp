// test_framing.cpp - CRC, frame encoding and the streaming decoder against the shared vectors and invariants.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "rbx1_proto.h"
#include "vectors.hpp"

using nlohmann::json;
using rbx1test::hex;
using rbx1test::load_vectors;
using rbx1test::unhex;

namespace {

// Records decoder events as JSON in the vectors' format.
struct Recorder {
  rbx1_decoder dec;
  json events = json::array();
  Recorder() { rbx1_decoder_init(&dec, on_frame, on_reject, this); }
  static void on_frame(void* ctx, const rbx1_frame* f) {
    static_cast<Recorder*>(ctx)->events.push_back(
        {{"frame", {{"seq", f->seq}, {"type", f->type}, {"payload", hex(f->payload, f->len)}, {"crc", f->crc}}}});
  }
  static void on_reject(void* ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
    json s = has_seq ? json(seq) : json(nullptr);
    static_cast<Recorder*>(ctx)->events.push_back(
        {{"reject", {{"status", std::string(rbx1_status_name(status))}, {"seq", s}}}});
  }
};

// Feeds wire in chunks; then, when after_timeout is given, the inter-byte timeout (rbx1_decoder_reset) and the
// events its rescan produced.
json decode_chunked(const std::vector<uint8_t>& wire, const std::vector<size_t>& chunks, bool* pending,
                    json* after_timeout = nullptr) {
  Recorder r;
  size_t pos = 0, k = 0;
  while (pos < wire.size()) {
    size_t n = std::min(wire.size() - pos, chunks[k++ % chunks.size()]);
    rbx1_decoder_feed(&r.dec, wire.data() + pos, n);
    pos += n;
  }
  *pending = rbx1_decoder_pending(&r.dec) != 0;
  json events = r.events;
  if (after_timeout) {
    r.events = json::array();
    EXPECT_EQ(rbx1_decoder_reset(&r.dec), *pending ? 1 : 0);
    EXPECT_FALSE(rbx1_decoder_pending(&r.dec));
    *after_timeout = r.events;
  }
  return events;
}

}  // namespace

TEST(Crc, CheckValueOfIsoHdlc) {
  const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(rbx1_crc32(check, sizeof check), 0xCBF43926u);
}

TEST(Crc, Vectors) {
  const json vs = load_vectors("crc.json");
  ASSERT_GE(vs.size(), 4u);
  for (const auto& v : vs) {
    auto data = unhex(v["data"]);
    EXPECT_EQ(rbx1_crc32(data.data(), data.size()), v["crc"].get<uint32_t>()) << v["data"];
    uint32_t crc = 0xFFFFFFFFu;  // the incremental form agrees
    for (uint8_t b : data) crc = rbx1_crc32_update(crc, b);
    EXPECT_EQ(~crc, v["crc"].get<uint32_t>());
  }
}

TEST(Budget, OverheadIsEightBytesAndMoveFrameIs34) {
  EXPECT_EQ(RBX1_FRAME_OVERHEAD, 8);
  EXPECT_EQ(RBX1_MAX_FRAME, 66);
  uint8_t out[RBX1_MAX_FRAME];
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 0, RBX1_MSG_STATUS, nullptr, 0), 8u);
  rbx1_move_req m = {{1, 2, 3, 4, 5, 6}, 100};
  uint8_t payload[RBX1_MAX_PAYLOAD];
  uint8_t len = rbx1_move_req_pack(&m, payload);
  EXPECT_EQ(len, 26);
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 0, RBX1_MSG_MOVE, payload, len), 34u);
}

TEST(Encode, RejectsOversizeAndSmallBuffers) {
  uint8_t payload[RBX1_MAX_PAYLOAD + 1] = {0};
  uint8_t out[RBX1_MAX_FRAME + 1];
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 1, 2, payload, RBX1_MAX_PAYLOAD + 1), 0u);
  EXPECT_EQ(rbx1_frame_encode(out, RBX1_MAX_FRAME, 1, 2, payload, RBX1_MAX_PAYLOAD), size_t(RBX1_MAX_FRAME));
  EXPECT_EQ(rbx1_frame_encode(out, 12, 1, 2, payload, 5), 0u);
  EXPECT_EQ(rbx1_frame_encode(out, 13, 1, 2, payload, 5), 13u);
}

TEST(Encode, MessageVectorsWireBytes) {
  const json vs = load_vectors("messages.json");
  ASSERT_EQ(vs.size(), 14u * 2 + 3);
  for (const auto& v : vs) {
    auto payload = unhex(v["payload"]);
    uint8_t out[RBX1_MAX_FRAME];
    size_t n = rbx1_frame_encode(out, sizeof out, v["seq"].get<uint8_t>(), v["type"].get<uint8_t>(), payload.data(),
                                 static_cast<uint8_t>(payload.size()));
    EXPECT_EQ(hex(out, n), v["wire"].get<std::string>()) << v["name"];
  }
}

TEST(Decoder, StreamVectorsInAnyChunking) {
  const json vs = load_vectors("streams.json");
  ASSERT_GE(vs.size(), 20u);
  const std::vector<std::vector<size_t>> chunkings = {{1 << 20}, {1}, {2}, {3, 1, 7}, {5, 64, 1}, {63}};
  for (const auto& v : vs) {
    auto wire = unhex(v["wire"]);
    for (const auto& ch : chunkings) {
      bool pending = false;
      json timeout;
      json got = decode_chunked(wire, ch, &pending, &timeout);
      EXPECT_EQ(got, v["events"]) << v["name"] << " chunk " << ch[0];
      EXPECT_EQ(pending, v["pending"].get<bool>()) << v["name"];
      EXPECT_EQ(timeout, v["after_timeout"]) << v["name"] << " chunk " << ch[0];
    }
  }
}

// A MOVE whose line damage leaves version 3's CRC-16 intact (vector crc16_collision): the CRC-32 rejects it.
TEST(Decoder, RejectsTheCrc16Collision) {
  const json crcs = load_vectors("crc.json");
  ASSERT_GE(crcs.size(), 2u);
  const auto sent = unhex(crcs[crcs.size() - 2]["data"]);  // the body sent, and as received
  const auto got = unhex(crcs[crcs.size() - 1]["data"]);
  for (const auto& v : load_vectors("streams.json")) {
    if (v["name"] != "crc16_collision") continue;
    auto wire = unhex(v["wire"]);
    ASSERT_EQ(wire.size(), got.size() + RBX1_FRAME_OVERHEAD - 3);
    EXPECT_TRUE(std::equal(got.begin(), got.end(), wire.begin() + 1));
    EXPECT_NE(sent, got);
    uint32_t rx = wire[wire.size() - 4] | (wire[wire.size() - 3] << 8) | (wire[wire.size() - 2] << 16) |
                  (uint32_t(wire[wire.size() - 1]) << 24);
    EXPECT_EQ(rbx1_crc32(sent.data(), sent.size()), rx);  // the CRC the sender wrote
    EXPECT_NE(rbx1_crc32(got.data(), got.size()), rx);
    bool pending = true;
    json events = decode_chunked(wire, {1}, &pending);
    EXPECT_EQ(events, json::parse(R"([{"reject": {"status": "BAD_CRC", "seq": 7}}])"));
    EXPECT_FALSE(pending);
    return;
  }
  FAIL() << "no vector crc16_collision";
}

TEST(Decoder, MessageVectorsDecodeToTheirFrame) {
  for (const auto& v : load_vectors("messages.json")) {
    auto wire = unhex(v["wire"]);
    bool pending = true;
    json got = decode_chunked(wire, {1}, &pending);
    ASSERT_EQ(got.size(), 1u) << v["name"];
    EXPECT_EQ(got[0]["frame"]["payload"], v["payload"]);
    EXPECT_EQ(got[0]["frame"]["type"], v["type"]);
    EXPECT_EQ(got[0]["frame"]["seq"], v["seq"]);
    EXPECT_EQ(got[0]["frame"]["crc"], v["crc"]);
    EXPECT_FALSE(pending);
  }
}

TEST(Decoder, TimeoutRescanFindsTheSwallowedFrameAndNextFrameDecodes) {
  auto vs = load_vectors("streams.json");
  std::vector<uint8_t> trunc, status;
  for (const auto& v : vs) {
    if (v["name"] == "truncated_swallows_short_frame") trunc = unhex(v["wire"]);
    if (v["name"] == "empty_payload") status = unhex(v["wire"]);
  }
  ASSERT_FALSE(trunc.empty());
  Recorder r;
  rbx1_decoder_feed(&r.dec, trunc.data(), trunc.size());
  EXPECT_TRUE(rbx1_decoder_pending(&r.dec));
  EXPECT_TRUE(r.events.empty());
  EXPECT_EQ(rbx1_decoder_reset(&r.dec), 1);
  ASSERT_EQ(r.events.size(), 1u);  // the STATUS the partial MOVE had swallowed
  EXPECT_EQ(r.events[0]["frame"]["type"], RBX1_MSG_STATUS);
  EXPECT_EQ(rbx1_decoder_reset(&r.dec), 0);
  rbx1_decoder_feed(&r.dec, status.data(), status.size());
  ASSERT_EQ(r.events.size(), 2u);
  EXPECT_EQ(r.events[1]["frame"]["type"], RBX1_MSG_STATUS);
}

TEST(Decoder, RandomFramesInRandomNoiseAreAllFound) {
  // Frames separated by noise without SYNC are always recovered, whatever the chunking.
  std::mt19937 rng(1234);
  std::vector<uint8_t> wire;
  std::vector<std::vector<uint8_t>> sent;
  for (int i = 0; i < 300; i++) {
    int noise = static_cast<int>(rng() % 5);
    for (int k = 0; k < noise; k++) {
      uint8_t b = static_cast<uint8_t>(rng());
      wire.push_back(b == RBX1_SYNC ? 0 : b);
    }
    uint8_t payload[RBX1_MAX_PAYLOAD], out[RBX1_MAX_FRAME];
    uint8_t len = static_cast<uint8_t>(rng() % (RBX1_MAX_PAYLOAD + 1));
    for (int k = 0; k < len; k++) payload[k] = static_cast<uint8_t>(rng());
    size_t n = rbx1_frame_encode(out, sizeof out, static_cast<uint8_t>(i), static_cast<uint8_t>(rng()), payload, len);
    sent.emplace_back(out, out + n);
    wire.insert(wire.end(), out, out + n);
  }
  bool pending = true;
  json got = decode_chunked(wire, {1, 9, 2, 33}, &pending);
  ASSERT_EQ(got.size(), sent.size());
  for (size_t i = 0; i < sent.size(); i++) {
    ASSERT_TRUE(got[i].contains("frame")) << i;
    EXPECT_EQ(got[i]["frame"]["seq"], i % 256);
    EXPECT_EQ(got[i]["frame"]["payload"], hex(sent[i].data() + 4, sent[i][1]));
  }
  EXPECT_FALSE(pending);
}
