// test_window.cpp - the receiver's window (rbx1_window.c) against the shared window vectors, and its RAM size.
#include <gtest/gtest.h>

#include <map>
#include <string>

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
                                                 {RBX1_WIN_UNKNOWN, "unknown"}};

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
      if (verdict == RBX1_WIN_NEW) {
        uint8_t answer = static_cast<uint8_t>(i);
        rbx1_window_record(&w, f.seq, f.crc, 0x40, &answer, 1);
      }
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
