// vision_test.cpp - the Vision class end to end: JSON shape, calibration scale, config table, bad frames.
#include <gtest/gtest.h>

#include "shapes.hpp"
#include "vision.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

TEST(Vision, JsonHasTheDesignFields) {
  VisionOptions o;
  o.px_per_cm = 20;
  std::string error;
  auto v = Vision::create(o, error);
  ASSERT_TRUE(v) << error;
  Scene s;
  cv::Mat img = render(s, {rectangle({200, 150}, 120, 40, 30), ellipse({450, 300}, 50, 30, -20)});
  nlohmann::json j;
  ASSERT_TRUE(v->process(img, j, error)) << error;
  EXPECT_EQ(j["image"]["width"], 640);
  EXPECT_EQ(j["image"]["height"], 480);
  EXPECT_DOUBLE_EQ(j["px_per_cm"].get<double>(), 20.0);
  ASSERT_EQ(j["objects"].size(), 2u);
  const auto& a = j["objects"][0];
  for (const char* key : {"index", "label", "match_score", "centroid_px", "centroid_cm", "area_px", "edge_points",
                          "orientation_deg", "axis_line", "elongation", "elongated", "grip", "touching",
                          "identification"})
    EXPECT_TRUE(a.contains(key)) << key;
  EXPECT_EQ(a.size(), 14u);
  EXPECT_TRUE(a["identification"].is_null());  // no library
  EXPECT_EQ(a["grip"].size(), 7u);
  EXPECT_TRUE(a["grip"]["reason"].is_null());
  EXPECT_FALSE(a["touching"].get<bool>());
  EXPECT_EQ(a["index"], 1);
  EXPECT_TRUE(a["label"].is_null());
  EXPECT_NEAR(a["centroid_px"][0].get<double>(), 200, 0.3);
  EXPECT_NEAR(a["centroid_cm"][0].get<double>(), 10, 0.02);
  EXPECT_NEAR(a["orientation_deg"].get<double>(), 30, 0.3);
  EXPECT_NEAR(a["grip"]["opening_px"].get<double>(), 40, 1.0);
  EXPECT_NEAR(a["grip"]["opening_cm"].get<double>(), 2.0, 0.05);
  EXPECT_NEAR(a["grip"]["angle_deg"].get<double>(), -60, 0.5);
  EXPECT_TRUE(a["grip"]["feasible"].get<bool>());
  EXPECT_NEAR(a["area_px"].get<double>(), 4800, 40);
}

TEST(Vision, UncalibratedHasNullCentimetres) {
  std::string error;
  auto v = Vision::create({}, error);
  ASSERT_TRUE(v) << error;
  nlohmann::json j;
  ASSERT_TRUE(v->process(render({}, {rectangle({300, 200}, 80, 50, 10)}), j, error)) << error;
  EXPECT_TRUE(j["px_per_cm"].is_null());
  ASSERT_EQ(j["objects"].size(), 1u);
  EXPECT_TRUE(j["objects"][0]["centroid_cm"].is_null());
  EXPECT_TRUE(j["objects"][0]["grip"]["opening_cm"].is_null());
}

TEST(Vision, GripperTooNarrowIsInfeasible) {
  VisionOptions o;
  o.px_per_cm = 10;
  o.gripper_max_cm = 3.0;
  std::string error;
  auto v = Vision::create(o, error);
  ASSERT_TRUE(v);
  nlohmann::json j;
  ASSERT_TRUE(v->process(render({}, {rectangle({150, 150}, 100, 25, 0), ellipse({420, 300}, 45, 45, 0)}), j, error));
  ASSERT_EQ(j["objects"].size(), 2u);
  EXPECT_TRUE(j["objects"][0]["grip"]["feasible"].get<bool>());   // 2.5 cm
  EXPECT_FALSE(j["objects"][1]["grip"]["feasible"].get<bool>());  // 9 cm
  EXPECT_EQ(j["objects"][1]["grip"]["reason"], "too_wide");
}

TEST(Vision, EmptyFrameIsAnError) {
  std::string error;
  auto v = Vision::create({}, error);
  nlohmann::json j;
  EXPECT_FALSE(v->process(cv::Mat(), j, error));
  EXPECT_NE(error.find("empty"), std::string::npos);
}

TEST(Vision, ZeroObjectsIsSuccess) {
  std::string error;
  auto v = Vision::create({}, error);
  nlohmann::json j;
  Scene s;
  s.noise_sigma = 6;
  ASSERT_TRUE(v->process(render(s, {}), j, error)) << error;
  EXPECT_EQ(j["objects"].size(), 0u);
}

TEST(Vision, ParsesTheVisionTable) {
  config::Errors errors;
  toml::table t = config::parse_text(
      "[vision]\nobjects = \"light\"\npx_per_cm = 25.5\ngripper_max_cm = 4\nfinger_width_cm = 0.6\n", errors);
  VisionOptions o;
  parse_vision_config(config::Section(t["vision"].as_table(), "vision", errors), o);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_EQ(o.objects, Polarity::Light);
  EXPECT_DOUBLE_EQ(o.px_per_cm, 25.5);
  EXPECT_DOUBLE_EQ(o.gripper_max_cm, 4);
  EXPECT_DOUBLE_EQ(o.finger_width_cm, 0.6);
}

TEST(Vision, VisionTableErrorsNameTheKey) {
  config::Errors errors;
  toml::table t = config::parse_text("[vision]\nobjects = \"grey\"\npx_per_cm = -1\ncolour = 3\n", errors);
  VisionOptions o;
  parse_vision_config(config::Section(t["vision"].as_table(), "vision", errors), o);
  ASSERT_EQ(errors.messages().size(), 3u) << errors.joined();
  EXPECT_NE(errors.joined().find("vision.objects"), std::string::npos);
  EXPECT_NE(errors.joined().find("vision.px_per_cm"), std::string::npos);
  EXPECT_NE(errors.joined().find("vision.colour: unknown key"), std::string::npos);
}

}  // namespace
}  // namespace rbx1::vision

namespace rbx1::vision {
namespace {

using namespace test;

TEST(Vision, SpeckSizeScalesWithTheFrame) {
  EXPECT_EQ(min_area_for({640, 480}), 40);
  EXPECT_EQ(min_area_for({1280, 720}), 120);
  EXPECT_EQ(min_area_for({160, 120}), 12);
  std::string error;
  auto v = Vision::create({}, error);
  ASSERT_TRUE(v) << error;
  // A 10x10 px blob with a real object: an object at 640x480, a speck (dust) at 1600x1200.
  for (auto [size, expect] : {std::pair{cv::Size(640, 480), 2u}, std::pair{cv::Size(1600, 1200), 1u}}) {
    Scene s;
    s.size = size;
    s.noise_sigma = 2;
    nlohmann::json j;
    ASSERT_TRUE(v->process(render(s, {rectangle({300, 200}, 10, 10, 0), rectangle({450, 300}, 120, 50, 10)}), j, error));
    EXPECT_EQ(j["objects"].size(), expect) << size;
  }
}

}  // namespace
}  // namespace rbx1::vision
