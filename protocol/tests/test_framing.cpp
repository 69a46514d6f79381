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
// events its rescan produced; then, when a vector's "then" is given, its wire (after the timeout) and its events.
json decode_chunked(const std::vector<uint8_t>& wire, const std::vector<size_t>& chunks, bool* pending,
                    json* after_timeout = nullptr, const json* then = nullptr, json* then_events = nullptr) {
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
  if (after_timeout && then) {
    r.events = json::array();
    auto more = unhex((*then)["wire"]);
    rbx1_decoder_feed(&r.dec, more.data(), more.size());
    *then_events = r.events;
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

TEST(Budget, OverheadIsTenBytesAndMoveFrameIs36) {
  EXPECT_EQ(RBX1_FRAME_OVERHEAD, 10);
  EXPECT_EQ(RBX1_FEC_BYTES, 2);
  EXPECT_EQ(RBX1_MAX_FRAME, 68);
  uint8_t out[RBX1_MAX_FRAME];
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 0, RBX1_MSG_STATUS, nullptr, 0), 10u);
  rbx1_move_req m = {{1, 2, 3, 4, 5, 6}, 100};
  uint8_t payload[RBX1_MAX_PAYLOAD];
  uint8_t len = rbx1_move_req_pack(&m, payload);
  EXPECT_EQ(len, 26);
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 0, RBX1_MSG_MOVE, payload, len), 36u);
}

TEST(Encode, RejectsOversizeAndSmallBuffers) {
  uint8_t payload[RBX1_MAX_PAYLOAD + 1] = {0};
  uint8_t out[RBX1_MAX_FRAME + 1];
  EXPECT_EQ(rbx1_frame_encode(out, sizeof out, 1, 2, payload, RBX1_MAX_PAYLOAD + 1), 0u);
  EXPECT_EQ(rbx1_frame_encode(out, RBX1_MAX_FRAME, 1, 2, payload, RBX1_MAX_PAYLOAD), size_t(RBX1_MAX_FRAME));
  EXPECT_EQ(rbx1_frame_encode(out, 14, 1, 2, payload, 5), 0u);
  EXPECT_EQ(rbx1_frame_encode(out, 15, 1, 2, payload, 5), 15u);
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
      json then;
      json got = decode_chunked(wire, ch, &pending, &timeout, v.contains("then") ? &v["then"] : nullptr, &then);
      EXPECT_EQ(got, v["events"]) << v["name"] << " chunk " << ch[0];
      EXPECT_EQ(pending, v["pending"].get<bool>()) << v["name"];
      EXPECT_EQ(timeout, v["after_timeout"]) << v["name"] << " chunk " << ch[0];
      if (v.contains("then")) {
        EXPECT_EQ(then, v["then"]["events"]) << v["name"] << " chunk " << ch[0];
      }
    }
  }
}

// Random damaged streams and the Python decoder's events for them: the C decoder agrees, in any chunking.
TEST(Decoder, AgreesWithThePythonDecoderOnRandomDamagedStreams) {
  const json vs = load_vectors("random_streams.json");
  ASSERT_GE(vs.size(), 100u);
  size_t frames = 0;
  for (const auto& v : vs) {
    auto wire = unhex(v["wire"]);
    for (const auto& ch : std::vector<std::vector<size_t>>{{1 << 20}, {1}, {3, 1, 7}}) {
      bool pending = false;
      json timeout;
      EXPECT_EQ(decode_chunked(wire, ch, &pending, &timeout), v["events"]) << v["name"] << " chunk " << ch[0];
      EXPECT_EQ(pending, v["pending"].get<bool>()) << v["name"];
      EXPECT_EQ(timeout, v["after_timeout"]) << v["name"] << " chunk " << ch[0];
    }
    frames += v["events"].size();
  }
  EXPECT_GT(frames, 100u);
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
    const uint8_t* c = wire.data() + wire.size() - 6;  // CRC 0..3, then the 2 parity bytes
    uint32_t rx = c[0] | (c[1] << 8) | (c[2] << 16) | (uint32_t(c[3]) << 24);
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

// ---- Version 5: Reed-Solomon parity (rbx1_fec_parity, rbx1_fec_locate) and the decoder's corrected readings ----

namespace {

// a * b in GF(2^8) mod 0x11D, bit by bit: an evaluation independent of the library's shift-and-XOR.
uint8_t gf_mul(uint8_t a, uint8_t b) {
  uint8_t r = 0;
  while (b) {
    if (b & 1) r ^= a;
    a = static_cast<uint8_t>((a << 1) ^ ((a & 0x80) ? 0x1D : 0));
    b >>= 1;
  }
  return r;
}

// The codeword (first byte the highest power) evaluated at x.
uint8_t evaluate(const std::vector<uint8_t>& code, uint8_t x) {
  uint8_t r = 0;
  for (uint8_t c : code) r = static_cast<uint8_t>(gf_mul(r, x) ^ c);
  return r;
}

std::vector<uint8_t> with_parity(std::vector<uint8_t> data) {
  uint8_t par[RBX1_FEC_BYTES];
  rbx1_fec_parity(data.data(), data.size(), par);
  data.insert(data.end(), par, par + RBX1_FEC_BYTES);
  return data;
}

std::vector<uint8_t> encode(uint8_t seq, uint8_t type, const std::vector<uint8_t>& payload) {
  uint8_t out[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(out, sizeof out, seq, type, payload.data(), static_cast<uint8_t>(payload.size()));
  return std::vector<uint8_t>(out, out + n);
}

std::vector<uint8_t> move_frame() {
  rbx1_move_req m = {{1000, -2000, 3000, -4000, 5000, 0}, 1500};
  uint8_t payload[RBX1_MAX_PAYLOAD];
  uint8_t len = rbx1_move_req_pack(&m, payload);
  return encode(7, RBX1_MSG_MOVE, std::vector<uint8_t>(payload, payload + len));
}

// The frame event an intact wire frame decodes to.
json frame_event(const std::vector<uint8_t>& w) {
  uint8_t n = w[1];
  const uint8_t* c = w.data() + 4 + n;
  uint32_t crc = c[0] | (c[1] << 8) | (c[2] << 16) | (uint32_t(c[3]) << 24);
  return {{"frame", {{"seq", w[2]}, {"type", w[3]}, {"payload", hex(w.data() + 4, n)}, {"crc", crc}}}};
}

}  // namespace

TEST(Fec, ParityVectors) {
  size_t n = 0;
  for (const auto& v : load_vectors("fec.json")) {
    if (!v.contains("parity")) continue;
    auto data = unhex(v["data"]);
    uint8_t par[RBX1_FEC_BYTES];
    rbx1_fec_parity(data.data(), data.size(), par);
    EXPECT_EQ(hex(par, 2), v["parity"].get<std::string>()) << v["name"];
    n++;
  }
  EXPECT_GE(n, 5u);
}

TEST(Fec, LocateVectors) {
  size_t n = 0, located = 0;
  for (const auto& v : load_vectors("fec.json")) {
    if (!v.contains("code")) continue;
    auto code = unhex(v["code"]);
    uint8_t error = 0;
    int at = rbx1_fec_locate(code.data(), code.size(), &error);
    EXPECT_EQ(at, v["at"].get<int>()) << v["name"];
    if (at >= 0) {
      EXPECT_EQ(error, v["error"].get<int>()) << v["name"];
      located++;
    }
    n++;
  }
  EXPECT_GE(n, 10u);
  EXPECT_GE(located, 5u);
}

// The parity makes the codeword vanish at x = 1 and x = 2 (divisible by (x + 1)(x + 2)), for every length.
TEST(Fec, ParityMakesTheCodewordDivisibleByTheGenerator) {
  std::mt19937 rng(5);
  for (size_t n = 0; n <= RBX1_MAX_FRAME - 3; n++) {
    std::vector<uint8_t> data(n);
    for (auto& b : data) b = static_cast<uint8_t>(rng());
    auto code = with_parity(data);
    EXPECT_EQ(evaluate(code, 1), 0) << n;
    EXPECT_EQ(evaluate(code, 2), 0) << n;
    uint8_t error = 0;
    EXPECT_EQ(rbx1_fec_locate(code.data(), code.size(), &error), -1) << n;
  }
}

// Every single-byte error, at every position of a 68-byte codeword (66 data bytes and the parity) and with every
// one of the 255 error values, is located with its value.
TEST(Fec, EverySingleByteErrorOfA68ByteCodewordIsLocated) {
  std::mt19937 rng(68);
  std::vector<uint8_t> data(66);
  for (auto& b : data) b = static_cast<uint8_t>(rng());
  const auto code = with_parity(data);
  ASSERT_EQ(code.size(), 68u);
  int wrong = 0;
  for (size_t i = 0; i < code.size(); i++) {
    for (int e = 1; e < 256; e++) {
      auto hit = code;
      hit[i] ^= static_cast<uint8_t>(e);
      uint8_t error = 0;
      int at = rbx1_fec_locate(hit.data(), hit.size(), &error);
      if (at != static_cast<int>(i) || error != e) wrong++;
      if (at >= 0) hit[at] ^= error;
      if (hit != code) wrong++;
    }
  }
  EXPECT_EQ(wrong, 0);
}

// Two damaged bytes are never "located" at one of them with the value that would undo both: the parity alone cannot
// tell them from one damaged byte elsewhere, which is why the CRC decides.
TEST(Fec, TwoErrorsAreNeverTakenForTheSentCodeword) {
  std::mt19937 rng(2);
  std::vector<uint8_t> data(33);
  for (auto& b : data) b = static_cast<uint8_t>(rng());
  const auto code = with_parity(data);
  int located = 0, refused = 0;
  for (int k = 0; k < 20000; k++) {
    size_t i = rng() % code.size(), j = rng() % code.size();
    if (i == j) continue;
    auto hit = code;
    hit[i] ^= static_cast<uint8_t>(1 + rng() % 255);
    hit[j] ^= static_cast<uint8_t>(1 + rng() % 255);
    uint8_t error = 0;
    int at = rbx1_fec_locate(hit.data(), hit.size(), &error);
    ASSERT_NE(at, -1);  // two errors always show in the syndromes (distance 3)
    if (at >= 0) {
      hit[at] ^= error;
      EXPECT_NE(hit, code);
      located++;
    } else {
      refused++;
    }
  }
  EXPECT_GT(located, 0);  // some are "corrected" into another codeword...
  EXPECT_GT(refused, located);  // ...most are refused outright
}

// The C results agree with the vectors the Python module wrote (fec.json, the wire bytes of messages.json).
TEST(Fec, FrameParityIsTheParityOfLenToCrc) {
  for (const auto& v : load_vectors("messages.json")) {
    auto wire = unhex(v["wire"]);
    std::vector<uint8_t> body(wire.begin() + 1, wire.end() - 2);
    EXPECT_EQ(with_parity(body), std::vector<uint8_t>(wire.begin() + 1, wire.end())) << v["name"];
  }
}

// Damages byte `first`, `first` + 1, ... of `frame` (sent right after `before`) with every error value, one at a time,
// and counts the streams whose events are not `want` or that leave something pending (the first few are reported).
static int wrong_after_single_damage(const std::vector<uint8_t>& before, const std::vector<uint8_t>& frame,
                                     size_t first, const json& want) {
  int wrong = 0;
  for (size_t i = first; i < frame.size(); i++) {
    for (int e = 1; e < 256; e++) {
      auto wire = before;
      wire.insert(wire.end(), frame.begin(), frame.end());
      wire[before.size() + i] ^= static_cast<uint8_t>(e);
      bool pending = true;
      json got = decode_chunked(wire, {i % 2 ? size_t(1) : size_t(64)}, &pending);
      if (got != want || pending) {
        if (wrong++ < 5) ADD_FAILURE() << "byte " << i << " error " << e << ": " << got.dump();
      }
    }
  }
  return wrong;
}

// Every byte after SYNC of a 36-byte MOVE frame, damaged with every error value, is delivered intact (corrected, its
// LEN repaired from TYPE, or a damaged parity byte skipped), with nothing left pending.
TEST(Decoder, EverySingleDamagedByteOfAMoveFrameIsDeliveredIntact) {
  const auto move = move_frame();
  ASSERT_EQ(move.size(), 36u);
  EXPECT_EQ(wrong_after_single_damage({}, move, 1, json::array({frame_event(move)})), 0);
}

// A STATUS, then a MOVE with any one byte damaged, its SYNC included (the byte right after a delivered frame is read
// as a SYNC whatever its value): both delivered, no rejection, nothing pending.
TEST(Decoder, EverySingleDamagedByteOfAMoveAfterAnotherFrameIsDeliveredIntact) {
  const auto move = move_frame(), status = encode(8, RBX1_MSG_STATUS, {});
  EXPECT_EQ(wrong_after_single_damage(status, move, 0, json::array({frame_event(status), frame_event(move)})), 0);
}

// Random frames with two damaged bytes after SYNC: never delivered with content other than what was sent (the CRC
// refuses what the parity "corrects" wrongly); most are rejected.
TEST(Decoder, RandomTwoByteDamageNeverDeliversWrongContent) {
  std::mt19937 rng(22);
  int intact = 0, rejected = 0;
  for (int k = 0; k < 20000; k++) {
    uint8_t type = static_cast<uint8_t>(1 + rng() % 14);
    if (rng() % 2) type = RBX1_RESPONSE(type);
    int len = (type & 0x80) ? rbx1_response_len(type & 0x7F) : rbx1_request_len(type);
    ASSERT_GE(len, 0);
    std::vector<uint8_t> payload(static_cast<size_t>(len));
    for (auto& b : payload) b = static_cast<uint8_t>(rng());
    const auto sent = encode(static_cast<uint8_t>(rng()), type, payload);
    auto hit = sent;
    size_t i = 1 + rng() % (sent.size() - 1), j = 1 + rng() % (sent.size() - 1);
    if (i == j) continue;
    hit[i] ^= static_cast<uint8_t>(1 + rng() % 255);
    hit[j] ^= static_cast<uint8_t>(1 + rng() % 255);
    bool pending = false;
    json timeout;
    json got = decode_chunked(hit, {1}, &pending, &timeout);
    got.insert(got.end(), timeout.begin(), timeout.end());
    bool delivered = false;
    for (const auto& ev : got) {
      if (!ev.contains("frame")) continue;
      ASSERT_EQ(ev, frame_event(sent)) << "bytes " << i << ", " << j << " of " << hex(sent.data(), sent.size());
      delivered = true;
    }
    (delivered ? intact : rejected)++;
  }
  EXPECT_GT(rejected, 15000);  // two damaged bytes after LEN..CRC are beyond the parity
  EXPECT_GT(intact, 0);        // both in the parity, or one in it: the CRC holds as received
}

// Each reading decides when its last byte arrives: as sent at the last CRC byte, corrected at the last parity byte,
// with TYPE's length (a damaged LEN) at that length's last parity byte.
TEST(Decoder, EachReadingDeliversAtItsLastByte) {
  const auto move = move_frame();  // LEN 26: CRC ends at byte 34, parity at 36
  struct Case {
    size_t at;
    uint8_t error;
    size_t delivered_after;
  } cases[] = {{0, 0, 34}, {10, 0x40, 36}, {33, 0x01, 36}, {34, 0x01, 34}, {1, 26 ^ 12, 36}, {1, 26 ^ 40, 36}};
  for (const auto& c : cases) {
    auto hit = move;
    hit[c.at] ^= c.error;
    Recorder r;
    size_t when = 0;
    for (size_t k = 0; k < hit.size(); k++) {
      rbx1_decoder_feed(&r.dec, &hit[k], 1);
      if (!r.events.empty() && when == 0) when = k + 1;
    }
    EXPECT_EQ(when, c.delivered_after) << "byte " << c.at << " error " << int(c.error);
    ASSERT_EQ(r.events.size(), 1u);
    EXPECT_EQ(r.events[0], frame_event(move));
    EXPECT_FALSE(rbx1_decoder_pending(&r.dec));
  }
}
