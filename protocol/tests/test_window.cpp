// test_window.cpp - the receiver's window (rbx1_window.c) against the shared window vectors (holds, releases and
// drops included), and its RAM size.
#include <gtest/gtest.h>

#include <cstring>

#include <map>
#include <string>
#include <vector>

#include "rbx1_window.h"
#include "vectors.hpp"

using nlohmann::json;
using rbx1test::load_vectors;
using rbx1test::unhex;

namespace {

const std::map<uint8_t, std::string> kVerdict = {{RBX1_WIN_NEW, "new"},
                                                 {RBX1_WIN_DUPLICATE, "duplicate"},
                                                 {RBX1_WIN_GAP, "gap"},
                                                 {RBX1_WIN_OLD, "old"},
                                                 {RBX1_WIN_BYPASS, "bypass"},
                                                 {RBX1_WIN_UNKNOWN, "unknown"},
                                                 {RBX1_WIN_HELD, "held"}};

std::vector<int> ints(const json& st, const char* key) {
  return st.contains(key) ? st[key].get<std::vector<int>>() : std::vector<int>{};
}

struct One {
  rbx1_frame f{};
  int n = 0;
  static void on_frame(void* ctx, const rbx1_frame* f) {
    auto* self = static_cast<One*>(ctx);
    self->f = *f;
    self->n++;
  }
};

rbx1_frame decode(const std::string& hex) {
  One one;
  rbx1_decoder d;
  rbx1_decoder_init(&d, One::on_frame, nullptr, &one);
  auto bytes = unhex(hex);
  rbx1_decoder_feed(&d, bytes.data(), bytes.size());
  EXPECT_EQ(one.n, 1) << hex;
  return one.f;
}

}  // namespace

TEST(Window, Vectors) {
  for (const auto& v : load_vectors("window.json")) {
    SCOPED_TRACE(v["name"].get<std::string>());
    rbx1_window w;
    rbx1_window_init(&w);
    std::map<uint8_t, int> first_held;  // SEQ -> the step that first held it
    int i = 0;
    for (const auto& st : v["steps"]) {
      SCOPED_TRACE("step " + std::to_string(i));
      rbx1_frame f = decode(st["wire"]);
      const rbx1_window_entry* dup = nullptr;
      uint8_t last = 0x5A;
      uint8_t verdict = rbx1_window_accept(&w, &f, &dup, &last);
      ASSERT_EQ(kVerdict.at(verdict), st["verdict"].get<std::string>());
      if (verdict == RBX1_WIN_DUPLICATE) {
        ASSERT_NE(dup, nullptr);
        EXPECT_EQ(dup->len, 1);
        EXPECT_EQ(dup->payload[0], st["answer_of"].get<int>());
        EXPECT_EQ(dup->type, 0x40);
      }
      if (st.contains("last_seq") && !st["last_seq"].is_null()) {
        EXPECT_EQ(last, st["last_seq"].get<int>());
      }
      if (verdict == RBX1_WIN_HELD) first_held.emplace(f.seq, i);
      std::vector<int> released, dropped;
      if (verdict == RBX1_WIN_NEW) {
        uint8_t answer = static_cast<uint8_t>(i);
        rbx1_window_record(&w, f.seq, f.crc, 0x40, &answer, 1);
        for (const rbx1_window_held* h; (h = rbx1_window_release(&w)) != nullptr;) {
          ASSERT_EQ(first_held.count(h->seq), 1u) << "released a SEQ never held: " << int(h->seq);
          released.push_back(first_held[h->seq]);
          first_held.erase(h->seq);
          answer = static_cast<uint8_t>(released.back());
          rbx1_window_record(&w, h->seq, h->crc, 0x40, &answer, 1);
        }
      }
      if (verdict == RBX1_WIN_BYPASS) {
        uint8_t seqs[RBX1_HELD_MAX];
        uint8_t n = rbx1_window_drop_held(&w, seqs);
        for (uint8_t k = 0; k < n; ++k) {
          dropped.push_back(seqs[k]);
          first_held.erase(seqs[k]);
        }
      }
      EXPECT_EQ(released, ints(st, "released"));
      EXPECT_EQ(dropped, ints(st, "dropped"));
      ++i;
    }
  }
}

TEST(Window, RemembersTheLongestResponseAndClipsLonger) {
  rbx1_window w;
  rbx1_window_init(&w);
  EXPECT_EQ(rbx1_window_last_seq(&w), 0xFF);
  uint8_t big[RBX1_MAX_PAYLOAD];
  for (int i = 0; i < RBX1_MAX_PAYLOAD; ++i) big[i] = static_cast<uint8_t>(i);
  rbx1_window_record(&w, 9, 0x1234, 0x82, big, RBX1_MAX_PAYLOAD);
  const rbx1_window_entry* dup = nullptr;
  ASSERT_EQ(rbx1_window_classify(&w, 9, 0x1234, &dup), RBX1_WIN_DUPLICATE);
  EXPECT_EQ(dup->len, RBX1_MAX_RESP_LEN);
  EXPECT_EQ(dup->payload[RBX1_STATUS_RESP_LEN - 1], RBX1_STATUS_RESP_LEN - 1);
  EXPECT_EQ(rbx1_window_last_seq(&w), 9);
  EXPECT_EQ(RBX1_MAX_RESP_LEN, RBX1_STATUS_RESP_LEN);  // STATUS is the longest answer to remember
}

TEST(Window, HeldFramesKeepTheirBytesAndWrongLengths) {
  // A held MOVE runs with its own bytes; a frame longer than any request is held by its length alone (it is
  // answered BAD_LENGTH, which needs nothing else).
  rbx1_window w;
  rbx1_window_init(&w);
  rbx1_frame f{};
  f.seq = 5;
  f.type = RBX1_MSG_STATUS;
  f.crc = 0x1111;
  const rbx1_window_entry* dup = nullptr;
  uint8_t last = 0;
  ASSERT_EQ(rbx1_window_accept(&w, &f, &dup, &last), RBX1_WIN_NEW);
  rbx1_window_record(&w, 5, 0x1111, 0x82, nullptr, 0);
  rbx1_frame move{};
  move.seq = 7;
  move.type = RBX1_MSG_MOVE;
  move.len = RBX1_MOVE_REQ_LEN;
  move.crc = 0x2222;
  for (int i = 0; i < RBX1_MOVE_REQ_LEN; ++i) move.payload[i] = static_cast<uint8_t>(100 + i);
  rbx1_frame longer = move;
  longer.seq = 8;
  longer.len = RBX1_MAX_PAYLOAD;
  longer.crc = 0x3333;
  ASSERT_EQ(rbx1_window_accept(&w, &move, &dup, &last), RBX1_WIN_HELD);
  ASSERT_EQ(rbx1_window_accept(&w, &longer, &dup, &last), RBX1_WIN_HELD);
  EXPECT_EQ(rbx1_window_release(&w), nullptr);  // SEQ 6 is missing
  rbx1_window_record(&w, 6, 0x4444, 0x82, nullptr, 0);
  const rbx1_window_held* h = rbx1_window_release(&w);
  ASSERT_NE(h, nullptr);
  EXPECT_EQ(h->seq, 7);
  EXPECT_EQ(h->type, RBX1_MSG_MOVE);
  EXPECT_EQ(h->len, RBX1_MOVE_REQ_LEN);
  EXPECT_EQ(0, std::memcmp(h->payload, move.payload, RBX1_MOVE_REQ_LEN));
  EXPECT_EQ(rbx1_window_release(&w), nullptr);  // 8 waits until 7 is recorded
  rbx1_window_record(&w, 7, 0x2222, 0x84, nullptr, 0);
  h = rbx1_window_release(&w);
  ASSERT_NE(h, nullptr);
  EXPECT_EQ(h->seq, 8);
  EXPECT_EQ(h->len, RBX1_MAX_PAYLOAD);
  EXPECT_EQ(RBX1_MAX_REQ_LEN, RBX1_MOVE_REQ_LEN);  // MOVE is the longest request to hold
}

TEST(Window, RamSize) {
  // PROTOCOL.md "Window" states the window's RAM: 8 remembered answers of 45 bytes and 7 held requests of 32 on
  // the AVR (1-byte alignment there; the host may pad).
  EXPECT_EQ(RBX1_HELD_MAX, RBX1_WINDOW - 1);
  EXPECT_GE(sizeof(rbx1_window_held), 32u);
  EXPECT_GE(sizeof(rbx1_window), 8u * 45 + 7u * 32 + 4);
}
