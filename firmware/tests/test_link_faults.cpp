// test_link_faults.cpp - rbx1-simfw's per-byte link fault injection: each fault at rate 1 and 0, order kept.
#include <gtest/gtest.h>

#include <vector>

#include "link_faults.hpp"

namespace rbx1::sim {
namespace {

std::vector<uint8_t> pass(const FaultRates& r, const std::vector<uint8_t>& in, double at_ms = 0) {
  LinkFaults f(r, 1);
  for (uint8_t b : in) f.push(b, 0);
  std::vector<uint8_t> out;
  f.deliver(at_ms, [&](uint8_t b) { out.push_back(b); });
  return out;
}

const std::vector<uint8_t> kBytes = {1, 2, 3, 4, 5, 6, 7, 8};

TEST(LinkFaults, CleanLineDeliversEverythingInOrder) { EXPECT_EQ(pass({}, kBytes), kBytes); }

TEST(LinkFaults, DropCorruptDuplicateAtRateOne) {
  FaultRates drop;
  drop.drop = 1;
  EXPECT_TRUE(pass(drop, kBytes).empty());
  FaultRates corrupt;
  corrupt.corrupt = 1;
  std::vector<uint8_t> c = pass(corrupt, kBytes);
  ASSERT_EQ(c.size(), kBytes.size());
  for (size_t i = 0; i < c.size(); i++) EXPECT_NE(c[i], kBytes[i]) << i;
  FaultRates dup;
  dup.duplicate = 1;
  std::vector<uint8_t> d = pass(dup, kBytes);
  ASSERT_EQ(d.size(), 2 * kBytes.size());
  for (size_t i = 0; i < kBytes.size(); i++) {
    EXPECT_EQ(d[2 * i], kBytes[i]);
    EXPECT_EQ(d[2 * i + 1], kBytes[i]);
  }
}

TEST(LinkFaults, DelayHoldsBytesBackAndKeepsOrder) {
  FaultRates delay;
  delay.delay_rate = 1;
  delay.delay_ms = 30;
  EXPECT_TRUE(pass(delay, kBytes, 29.9).empty());
  EXPECT_EQ(pass(delay, kBytes, 30.0), kBytes);
}

TEST(LinkFaults, RatesAreRoughlyHonoured) {
  FaultRates r;
  r.drop = 0.1;
  LinkFaults f(r, 42);
  for (int i = 0; i < 10000; i++) f.push((uint8_t)i, 0);
  EXPECT_NEAR((double)f.dropped(), 1000.0, 150.0);
}

}  // namespace
}  // namespace rbx1::sim
