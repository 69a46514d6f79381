// scan_json_test.cpp - the scan as a struct and its one JSON writer: the document's exact text for a known scan,
// and on real frames (the demo scene, the corpus photos) each reported figure is the pipeline's rounded as
// published, written to the JSON unchanged.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "image_io.hpp"
#include "scan_json.hpp"
#include "vision.hpp"

namespace rbx1::vision {
namespace {

using nlohmann::json;

ScanObject bolt() {
  ScanObject o;
  o.index = 1;
  o.identity = {"bolt", 0.9321};
  o.centroid_px = {120.5, 80.25};
  o.centroid_cm = cv::Point2d(3.0125, 2.0063);
  o.area_px = 600;
  o.edge_points = 96;
  o.pose.orientation_deg = 30.5;
  o.pose.slope = 0.58905;
  o.pose.intercept = 9.271;
  o.pose.elongation = 3.2;
  o.pose.elongated = true;
  o.grip.p1 = {110.125, 90.5};
  o.grip.p2 = {130.875, 70.0};
  o.grip.opening_px = 29.171;
  o.grip.opening_cm = 0.7293;
  o.grip.angle_deg = -44.65;
  o.grip.feasible = true;
  o.grip.reason = GripReason::None;
  return o;
}

TEST(ScanJson, WritesTheDocumentExactly) {
  Scan s;
  s.image = {640, 480};
  s.px_per_cm = 40.0;
  s.objects.push_back(bolt());
  ScanObject unknown;  // uncalibrated figures, no label, a grip that does not fit
  unknown.index = 2;
  unknown.identity = {std::nullopt, std::nullopt};
  unknown.centroid_px = {10, 20};
  unknown.area_px = 100;
  unknown.grip.feasible = false;
  unknown.grip.reason = GripReason::TooWide;
  unknown.touching = true;
  s.objects.push_back(unknown);
  EXPECT_EQ(json(s).dump(),
            R"({"image":{"height":480,"width":640},"objects":[)"
            R"({"area_px":600,"axis_line":{"intercept":9.271,"slope":0.58905},"centroid_cm":[3.0125,2.0063],)"
            R"("centroid_px":[120.5,80.25],"edge_points":96,"elongated":true,"elongation":3.2,)"
            R"("grip":{"angle_deg":-44.65,"feasible":true,"opening_cm":0.7293,"opening_px":29.171,)"
            R"("p1_px":[110.125,90.5],"p2_px":[130.875,70.0],"reason":null},"identification":null,"index":1,"label":"bolt",)"
            R"("match_score":0.9321,"orientation_deg":30.5,"touching":false},)"
            R"({"area_px":100,"axis_line":{"intercept":null,"slope":null},"centroid_cm":null,"centroid_px":[10.0,20.0],)"
            R"("edge_points":0,"elongated":false,"elongation":1.0,"grip":{"angle_deg":0.0,"feasible":false,)"
            R"("opening_cm":null,"opening_px":0.0,"p1_px":[0.0,0.0],"p2_px":[0.0,0.0],"reason":"too_wide"},)"
            R"("identification":null,"index":2,"label":null,"match_score":null,"orientation_deg":0.0,"touching":true}],"px_per_cm":40.0})");
  // No warnings key unless the method could not decide; uncalibrated: px_per_cm null.
  s.px_per_cm.reset();
  s.objects.clear();
  s.warnings = {"no table found"};
  EXPECT_EQ(json(s).dump(),
            R"({"image":{"height":480,"width":640},"objects":[],"px_per_cm":null,"warnings":["no table found"]})");
}

// |written - exact| within half the figure's rounding quantum (the JSON's decimals).
void expect_rounded(double written, double exact, double q, const std::string& what) {
  EXPECT_LE(std::abs(written - exact), q / 2 + 1e-12) << what << ": " << written << " vs " << exact;
  EXPECT_NEAR(std::round(written / q) * q, written, 1e-9) << what << " has more decimals than " << q;
}

// Every figure of o as the document carries it.
void expect_written(const ScanObject& o, const json& j) {
  const std::string at = "object " + std::to_string(o.index);
  EXPECT_EQ(j["index"], o.index) << at;
  EXPECT_EQ(j["label"], o.identity.label ? json(*o.identity.label) : json(nullptr)) << at;
  EXPECT_EQ(j["match_score"], number_json(o.identity.score)) << at;
  EXPECT_EQ(j["centroid_px"], json({o.centroid_px.x, o.centroid_px.y})) << at;
  EXPECT_EQ(j["centroid_cm"], point_json(o.centroid_cm)) << at;
  EXPECT_EQ(j["area_px"], o.area_px) << at;
  EXPECT_EQ(j["edge_points"], o.edge_points) << at;
  EXPECT_EQ(j["orientation_deg"], o.pose.orientation_deg) << at;
  EXPECT_EQ(j["axis_line"]["slope"], number_json(o.pose.slope)) << at;
  EXPECT_EQ(j["axis_line"]["intercept"], number_json(o.pose.intercept)) << at;
  EXPECT_EQ(j["elongation"], o.pose.elongation) << at;
  EXPECT_EQ(j["elongated"], o.pose.elongated) << at;
  EXPECT_EQ(j["touching"], o.touching) << at;
  const json& g = j["grip"];
  EXPECT_EQ(g["p1_px"], json({o.grip.p1.x, o.grip.p1.y})) << at;
  EXPECT_EQ(g["p2_px"], json({o.grip.p2.x, o.grip.p2.y})) << at;
  EXPECT_EQ(g["opening_px"], o.grip.opening_px) << at;
  EXPECT_EQ(g["opening_cm"], number_json(o.grip.opening_cm)) << at;
  EXPECT_EQ(g["angle_deg"], o.grip.angle_deg) << at;
  EXPECT_EQ(g["feasible"], o.grip.feasible) << at;
  const char* why = o.grip.feasible ? nullptr : grip_reason_name(o.grip.reason);
  EXPECT_EQ(g["reason"], why ? json(why) : json(nullptr)) << at;
}

// The pipeline's figures of d, rounded as published.
void expect_scan_of(const DetectedObject& d, const ScanObject& o) {
  const std::string at = "object " + std::to_string(d.index);
  EXPECT_EQ(o.index, d.index);
  EXPECT_EQ(o.identity.label, d.identity.label) << at;
  EXPECT_EQ(o.identity.score.has_value(), d.identity.label.has_value()) << at;  // no score without a label
  if (o.identity.score) expect_rounded(*o.identity.score, *d.identity.score, 1e-4, at + " match_score");
  expect_rounded(o.centroid_px.x, d.geometry.centroid.x, 1e-3, at + " centroid_px");
  expect_rounded(o.centroid_px.y, d.geometry.centroid.y, 1e-3, at + " centroid_px");
  ASSERT_EQ(o.centroid_cm.has_value(), d.centroid_cm.has_value()) << at;
  if (o.centroid_cm) {
    expect_rounded(o.centroid_cm->x, d.centroid_cm->x, 1e-4, at + " centroid_cm");
    expect_rounded(o.centroid_cm->y, d.centroid_cm->y, 1e-4, at + " centroid_cm");
  }
  EXPECT_EQ(o.area_px, std::lround(d.geometry.area_px)) << at;
  EXPECT_EQ(o.edge_points, d.geometry.edge_pixels) << at;
  expect_rounded(o.pose.orientation_deg, d.pose.orientation_deg, 1e-3, at + " orientation_deg");
  expect_rounded(o.pose.elongation, d.pose.elongation, 1e-3, at + " elongation");
  if (d.pose.slope) expect_rounded(*o.pose.slope, *d.pose.slope, 1e-5, at + " slope");
  expect_rounded(o.grip.opening_px, d.grip.opening_px, 1e-3, at + " opening_px");
  expect_rounded(o.grip.angle_deg, d.grip.angle_deg, 1e-3, at + " angle_deg");
  expect_rounded(o.grip.p2.x, d.grip.p2.x, 1e-3, at + " p2_px");
  if (d.grip.opening_cm) expect_rounded(*o.grip.opening_cm, *d.grip.opening_cm, 1e-4, at + " opening_cm");
  EXPECT_EQ(o.grip.feasible, d.grip.feasible) << at;
  EXPECT_EQ(o.touching, d.touching) << at;
}

struct Frame {
  const char* image;
  VisionOptions opt;
  size_t min_objects;
};

VisionOptions demo_options() {  // as data/rbx1.toml's [vision]
  VisionOptions o;
  o.background_path = RBX1_DATA_DIR "/demo/background.png";
  o.library_path = RBX1_DATA_DIR "/demo/library.json";
  o.px_per_cm = 40;
  return o;
}

TEST(ScanJson, RealFramesAreTheirDetectionRoundedAndWrittenUnchanged) {
  const Frame frames[] = {{"demo/scene.png", demo_options(), 5}, {"corpus/stuff.jpg", {}, 1},
                          {"corpus/pca_test1.jpg", {}, 1},      {"corpus/smarties.png", {}, 1},
                          {"corpus/coins.png", {}, 1},          {"corpus/water_coins.jpg", {}, 1}};
  for (const Frame& f : frames) {
    SCOPED_TRACE(f.image);
    std::string error;
    auto v = Vision::create(f.opt, error);
    ASSERT_TRUE(v) << error;
    cv::Mat img;
    ASSERT_TRUE(read_image(std::string(RBX1_DATA_DIR "/") + f.image, img, error)) << error;
    Detection det;
    cv::Mat processed;
    ASSERT_TRUE(v->run(img, det, processed, error)) << error;
    Scan s = v->scan(det);
    ASSERT_GE(s.objects.size(), f.min_objects);
    ASSERT_EQ(s.objects.size(), det.objects.size());
    EXPECT_EQ(s.image, det.size);
    EXPECT_EQ(s.px_per_cm.has_value(), v->calibrated());
    EXPECT_EQ(s.warnings, det.warnings);
    json j = s;
    ASSERT_EQ(j["objects"].size(), s.objects.size());
    EXPECT_EQ(j["image"], json({{"width", img.cols}, {"height", img.rows}}));
    EXPECT_EQ(j["px_per_cm"], number_json(s.px_per_cm));
    EXPECT_EQ(j.contains("warnings"), !det.warnings.empty());
    for (size_t i = 0; i < s.objects.size(); ++i) {
      expect_scan_of(det.objects[i], s.objects[i]);
      expect_written(s.objects[i], j["objects"][i]);
    }
    // The demo's library names every object in its scene.
    if (f.opt.library_path.size())
      for (const ScanObject& o : s.objects) EXPECT_TRUE(o.identity.label) << "object " << o.index;
  }
}

}  // namespace
}  // namespace rbx1::vision
