// window_sender_test.cpp - the C++ window sender (window_sender.cpp, Link::stream's steps) reproduces every shared
// sender trace step by step (protocol/vectors/sender_traces.json, written from the Python sender; its pytest,
// protocol/python/tests/test_sender.py, reads the same file).
#include <gtest/gtest.h>

#include <cerrno>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "window_sender.hpp"

namespace rbx1::link {
namespace {

using Clock = WindowSender::Clock;
using nlohmann::json;

const json& traces() {
  static const json all = [] {
    std::ifstream in(std::string(RBX1_VECTORS_DIR) + "/sender_traces.json");
    return in ? json::parse(in)["vectors"] : json::array();
  }();
  return all;
}

uint8_t reason_code(const std::string& name) {
  for (int s = 0; s < 256; ++s)
    if (name == rbx1_status_name(static_cast<uint8_t>(s))) return static_cast<uint8_t>(s);
  ADD_FAILURE() << "unknown NAK reason " << name;
  return 0xFF;
}

// A trace's event as the frame the reader hands over: ["R", seq, type] a response of zeros, ["N", seq, reason] a NAK.
rbx1_frame received(const json& ev) {
  rbx1_frame f{};
  f.seq = ev[1].get<uint8_t>();
  if (ev[0] == "R") {
    const uint8_t type = ev[2].get<uint8_t>();
    f.type = RBX1_RESPONSE(type);
    f.len = static_cast<uint8_t>(std::max(0, rbx1_response_len(type)));
  } else {
    f.type = RBX1_MSG_NAK;
    f.len = RBX1_NAK_LEN;
    f.payload[0] = reason_code(ev[2].get<std::string>());
  }
  return f;
}

json writes_json(const std::vector<SenderWrite>& writes) {
  json out = json::array();
  for (const SenderWrite& w : writes)
    out.push_back({w.frames, w.probe ? json(w.probe_seq) : json(nullptr)});
  return out;
}

const char* result_name(int error) {
  return error == 0 ? "ok" : error == -EPROTO ? "seq_old" : error == -ETIMEDOUT ? "link_down" : "other";
}

class SenderTraces : public testing::TestWithParam<size_t> {};

TEST_P(SenderTraces, Reproduced) {
  const json& v = traces()[GetParam()];
  std::vector<uint8_t> types, seqs, sizes;
  for (size_t i = 0; i < v["types"].size(); ++i) {
    types.push_back(v["types"][i].get<uint8_t>());
    seqs.push_back(static_cast<uint8_t>(v["first_seq"].get<int>() + i));
    sizes.push_back(static_cast<uint8_t>(RBX1_FRAME_OVERHEAD + std::max(0, rbx1_request_len(types.back()))));
  }
  WindowSender s(types, seqs, sizes,
                 {v["window"].get<size_t>(), v["ahead"].get<uint32_t>(), v["timeout_ms"].get<int>(),
                  v["baud"].get<int>(), v["retries"].get<int>()});
  const Clock::time_point t0{};  // the trace's time 0 (any origin: only differences count)
  auto at = [&](const json& step) { return t0 + std::chrono::microseconds(step["at_us"].get<int64_t>()); };
  const json& steps = v["steps"];
  ASSERT_EQ(writes_json(s.start(at(steps[0]))), steps[0]["out"]);
  for (size_t k = 1; k < steps.size(); ++k) {
    const json& step = steps[k];
    ASSERT_FALSE(s.finished()) << "step " << k << ": finished early";
    for (const json& ev : step["in"]) s.feed(received(ev));
    ASSERT_EQ(writes_json(s.step(at(step))), step["out"]) << "step " << k << " at " << step["at_us"] << " us";
    if (step.contains("deadline_us")) {
      auto us = std::chrono::duration_cast<std::chrono::nanoseconds>(s.deadline() - t0).count() / 1000.0;
      EXPECT_NEAR(us, step["deadline_us"].get<double>(), 3.0) << "step " << k;
    }
  }
  EXPECT_TRUE(s.finished());
  EXPECT_EQ(result_name(s.error()), v["result"].get<std::string>());
  for (size_t i = 0; i < types.size(); ++i) EXPECT_EQ(s.answered(i), v["answered"][i].get<bool>()) << "request " << i;
  EXPECT_EQ(s.counters().retransmissions, v["retransmissions"].get<uint64_t>());
  EXPECT_EQ(s.counters().timeouts, v["timeouts"].get<uint64_t>());
  EXPECT_EQ(s.counters().probes, v["probes"].get<uint64_t>());
}

INSTANTIATE_TEST_SUITE_P(Shared, SenderTraces, testing::Range<size_t>(0, traces().size()),
                         [](const testing::TestParamInfo<size_t>& info) {
                           return traces()[info.param]["name"].get<std::string>();
                         });

TEST(SenderTraces, FileIsThere) { EXPECT_GE(traces().size(), 15u) << RBX1_VECTORS_DIR "/sender_traces.json"; }

}  // namespace
}  // namespace rbx1::link
