// arm_config_test.cpp - defaults, the written-out defaults.toml, and errors that name their key.
#include "arm_config.hpp"

#include <gtest/gtest.h>

#include <algorithm>

using namespace rbx1::arm;
using rbx1::config::Errors;
using rbx1::config::Section;

namespace {

// Parses `text`, then its [arm] table; returns parse_arm_config's result.
bool parse(const std::string& text, ArmConfig& out, Errors& errors) {
  toml::table t = rbx1::config::parse_text(text, errors);
  Section root(&t, "", errors);
  return parse_arm_config(root.section("arm"), out);
}

bool has_message(const Errors& e, const std::string& prefix) {
  return std::any_of(e.messages().begin(), e.messages().end(),
                     [&](const std::string& m) { return m.rfind(prefix, 0) == 0; });
}

}  // namespace

TEST(ArmConfig, EmptyTableGivesDefaults) {
  Errors errors;
  ArmConfig c;
  c.links.tool_mm = 1;  // parse must start from the defaults, not from what out held
  EXPECT_TRUE(parse("[arm]\n", c, errors)) << errors.joined();
  EXPECT_TRUE(c == ArmConfig{});
  EXPECT_DOUBLE_EQ(c.joints[2].reduction, 21.5);
  EXPECT_DOUBLE_EQ(c.joints[4].reduction, 4.67);
  ASSERT_EQ(c.places.count("tray"), 1u);
}

TEST(ArmConfig, AbsentTableGivesDefaults) {
  Errors errors;
  ArmConfig c;
  EXPECT_TRUE(parse("", c, errors)) << errors.joined();
  EXPECT_TRUE(c == default_arm_config());
}

TEST(ArmConfig, DefaultsTomlParsesToTheBuiltInDefaults) {
  Errors errors;
  toml::table t = rbx1::config::load_file(RBX1_ARM_DEFAULTS_TOML, errors);
  ASSERT_TRUE(errors.ok()) << errors.joined();
  ASSERT_TRUE(t.contains("arm"));
  Section root(&t, "", errors);
  ArmConfig c;
  EXPECT_TRUE(parse_arm_config(root.section("arm"), c)) << errors.joined();
  EXPECT_TRUE(c == default_arm_config());
  // Every key of the snippet is spelled as the parser reads it: one unknown key would have been an error above.
  EXPECT_TRUE(errors.ok()) << errors.joined();
}

TEST(ArmConfig, ReadsEverySection) {
  Errors errors;
  ArmConfig c;
  EXPECT_TRUE(parse(R"([arm.links]
forearm_mm = 200
[arm.joints.j3]
reduction = 20
microsteps = 32
direction = -1
zero_deg = -90
max_speed_steps_s = 12000
accel_steps_s2 = 50000
[arm.gripper]
closed_us = 1900
open_us = 1100
[arm.poses]
home = [0, 10, 20, 0, 30, 0]
[arm.camera]
origin_mm = [1, 2]
rotation_deg = 45
flip_y = false
[arm.places.tray]
x_mm = 100
y_mm = -200
[arm.heights]
table_z_mm = -12.5
[arm.speeds]
joint_speed_deg_s = 45
min_move_ms = 0
)",
                    c, errors))
      << errors.joined();
  EXPECT_DOUBLE_EQ(c.links.forearm_mm, 200);
  EXPECT_DOUBLE_EQ(c.joints[2].reduction, 20);
  EXPECT_EQ(c.joints[2].microsteps, 32);
  EXPECT_EQ(c.joints[2].direction, -1);
  EXPECT_DOUBLE_EQ(c.joints[2].zero_deg, -90);
  EXPECT_EQ(c.joints[2].max_speed_steps_s, 12000);
  EXPECT_EQ(c.joints[2].accel_steps_s2, 50000);
  EXPECT_EQ(c.joints[1].max_speed_steps_s, 4000);  // the firmware's defaults
  EXPECT_EQ(c.joints[1].accel_steps_s2, 8000);
  EXPECT_EQ(c.gripper.closed_us, 1900);
  EXPECT_EQ(c.gripper.open_us, 1100);
  EXPECT_EQ(c.home, (Joints{0, 10, 20, 0, 30, 0}));
  EXPECT_DOUBLE_EQ(c.camera.origin_y_mm, 2);
  EXPECT_DOUBLE_EQ(c.camera.rotation_deg, 45);
  EXPECT_FALSE(c.camera.flip_y);
  ASSERT_EQ(c.places.size(), 1u);
  EXPECT_EQ(c.places["tray"], (Place{100, -200, 0, 0}));
  EXPECT_DOUBLE_EQ(c.heights.table_z_mm, -12.5);
  EXPECT_DOUBLE_EQ(c.speeds.joint_speed_deg_s, 45);
  EXPECT_EQ(c.speeds.min_move_ms, 0);
  // Untouched keys keep their defaults.
  EXPECT_DOUBLE_EQ(c.joints[0].reduction, 10.67);
  EXPECT_DOUBLE_EQ(c.links.upper_arm_mm, 221);
}

TEST(ArmConfig, ErrorsNameTheirKeys) {
  Errors errors;
  ArmConfig c;
  EXPECT_FALSE(parse(R"([arm]
speed = 3
[arm.links]
lenght_mm = 3
upper_arm_mm = -5
[arm.joints.j2]
direction = 0
max_speed_steps_s = 20001
accel_steps_s2 = 0
[arm.joints.j3]
reduction = "x"
min_deg = 50
max_deg = 40
[arm.joints.j7]
reduction = 1
[arm.gripper]
closed_us = 1500
open_us = 1500
[arm.poses]
home = [0, 0, 0, 0, 0]
scan = [0, 0, 0, 0, 170, 0]
[arm.camera]
origin_mm = [1, 2, 3]
[arm.places.tray]
y_mm = 3
[arm.heights]
approach_clearance_mm = 10
[arm.speeds]
joint_speed_deg_s = 0
)",
                     c, errors));
  const char* expected[] = {
      "arm.speed: unknown key",
      "arm.links.lenght_mm: unknown key",
      "arm.links.upper_arm_mm: must be within [10, 2000]",
      "arm.joints.j2.direction: must be 1 or -1",
      "arm.joints.j2.max_speed_steps_s: must be within [1, 20000]",
      "arm.joints.j2.accel_steps_s2: must be within [1, 200000]",
      "arm.joints.j3.reduction: must be a number",
      "arm.joints.j3.min_deg: must be below max_deg (50 >= 40)",
      "arm.joints.j7: unknown key",
      "arm.gripper.open_us: must differ from closed_us",
      "arm.poses.home: must be an array of 6 numbers",
      "arm.poses.scan[4]: J5 (wrist pitch) at 170 deg is outside its limits [-115, 115]",
      "arm.camera.origin_mm: must be an array of 2 numbers",
      "arm.places.tray.x_mm: missing",
      "arm.heights.approach_clearance_mm: must exceed gripper.finger_depth_mm (15)",
      "arm.speeds.joint_speed_deg_s: must be within [0.1, 360]",
  };
  for (const char* e : expected) EXPECT_TRUE(has_message(errors, e)) << "missing: " << e << "\ngot:\n" << errors.joined();
  EXPECT_EQ(errors.messages().size(), std::size(expected)) << errors.joined();
  // A bad value keeps its default.
  EXPECT_DOUBLE_EQ(c.links.upper_arm_mm, 221);
  EXPECT_EQ(c.joints[1].direction, 1);
}

TEST(ArmConfig, ReturnsTrueWhenOnlyEarlierSectionsHadErrors) {
  Errors errors;
  errors.add("camera.fps", "must be within [1, 120]");
  ArmConfig c;
  toml::table t;
  Section root(&t, "", errors);
  EXPECT_TRUE(parse_arm_config(root.section("arm"), c));
  EXPECT_EQ(errors.messages().size(), 1u);
}

TEST(ArmConfig, PlacesTableReplacesTheDefaults) {
  Errors errors;
  ArmConfig c;
  EXPECT_TRUE(parse("[arm.places]\n", c, errors)) << errors.joined();
  EXPECT_TRUE(c.places.empty());
}

TEST(ArmConfig, NamedPlacesOfAnyName) {
  Errors errors;
  ArmConfig c;
  EXPECT_TRUE(parse("[arm.places.bin]\nx_mm = 1\ny_mm = 2\nz_mm = 3\nyaw_deg = 4\n", c, errors)) << errors.joined();
  ASSERT_EQ(c.places.size(), 1u);
  EXPECT_EQ(c.places["bin"], (Place{1, 2, 3, 4}));
}

TEST(ArmConfig, JointNames) {
  EXPECT_STREQ(joint_name(0), "base yaw");
  EXPECT_STREQ(joint_name(3), "forearm roll");
  EXPECT_STREQ(joint_name(5), "wrist roll");
}
