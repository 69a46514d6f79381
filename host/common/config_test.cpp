// config_test.cpp - range checks, type checks, unknown keys and parse errors all name the key.
#include "config.hpp"

#include <gtest/gtest.h>

#include <algorithm>

using namespace rbx1::config;

TEST(Config, ReadsValuesAndDefaults) {
  Errors errors;
  toml::table t = parse_text("[arm]\nspeed = 2.5\ncount = 3\nname = \"x\"\nlinks = [1, 2.5, 3]\n", errors);
  Section root(&t, "", errors);
  Section arm = root.section("arm");
  EXPECT_DOUBLE_EQ(arm.number("speed", 1, 0, 10), 2.5);
  EXPECT_EQ(arm.integer("count", 1, 0, 10), 3);
  EXPECT_EQ(arm.string("name", "y"), "x");
  EXPECT_EQ(arm.numbers("links", {0, 0, 0}, 0, 10), (std::vector<double>{1, 2.5, 3}));
  EXPECT_DOUBLE_EQ(arm.number("absent", 7, 0, 10), 7);
  arm.reject_unknown();
  EXPECT_TRUE(errors.ok()) << errors.joined();
}

TEST(Config, ErrorsNameTheKey) {
  Errors errors;
  toml::table t = parse_text("[arm]\nspeed = 20\ncount = 1.5\nlinks = [1, 2]\ntypo = 1\n", errors);
  Section root(&t, "", errors);
  Section arm = root.section("arm");
  EXPECT_DOUBLE_EQ(arm.number("speed", 1, 0, 10), 1);
  EXPECT_EQ(arm.integer("count", 4, 0, 10), 4);
  arm.numbers("links", {0, 0, 0}, 0, 10);
  arm.reject_unknown();
  ASSERT_EQ(errors.messages().size(), 4u) << errors.joined();
  EXPECT_EQ(errors.messages()[0].rfind("arm.speed: must be within [0, 10]", 0), 0u);
  EXPECT_EQ(errors.messages()[1], "arm.count: must be an integer");
  EXPECT_EQ(errors.messages()[2], "arm.links: must be an array of 3 numbers");
  EXPECT_EQ(errors.messages()[3], "arm.typo: unknown key");
}

TEST(Config, ParseErrorGivesLineAndColumn) {
  Errors errors;
  parse_text("[arm\nspeed = 1\n", errors);
  ASSERT_EQ(errors.messages().size(), 1u);
  EXPECT_EQ(errors.messages()[0].rfind("config:1:", 0), 0u) << errors.joined();
}

TEST(Config, MissingFileIsAnError) {
  Errors errors;
  load_file("/nonexistent/rbx1.toml", errors);
  ASSERT_EQ(errors.messages().size(), 1u);
  EXPECT_EQ(errors.messages()[0], "/nonexistent/rbx1.toml: cannot be read");
}

TEST(Config, KeysListsTheTable) {
  Errors errors;
  toml::table t = parse_text("[places.tray]\nx = 1\n[places.bin]\nx = 2\n", errors);
  Section root(&t, "", errors);
  Section places = root.section("places");
  std::vector<std::string> keys = places.keys();
  std::sort(keys.begin(), keys.end());
  EXPECT_EQ(keys, (std::vector<std::string>{"bin", "tray"}));
  EXPECT_TRUE(root.section("absent").keys().empty());
}
