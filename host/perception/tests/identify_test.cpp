// identify_test.cpp - identification against taught profiles: 9 classes, 180-degree turns, mirror images,
// non-star-shaped objects, unknown objects, and the library file (round trip, corrupt files).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "image_io.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;
using Maker = std::function<Poly(cv::Point2d, double)>;  // centre, angle

struct Class {
  const char* name;
  Maker make;
};

std::vector<Class> classes() {
  return {
      {"bar", [](cv::Point2d c, double a) { return rectangle(c, 110, 36, a); }},
      {"block", [](cv::Point2d c, double a) { return rectangle(c, 90, 55, a); }},
      {"oval", [](cv::Point2d c, double a) { return ellipse(c, 55, 28, a); }},
      {"triangle", [](cv::Point2d c, double a) { return triangle(c, 90, a); }},
      {"ell", [](cv::Point2d c, double a) { return l_shape(c, 90, 30, a); }},
      {"ell-mirrored", [](cv::Point2d c, double a) { return l_shape(c, 90, 30, a, true); }},
      {"star", [](cv::Point2d c, double a) { return star(c, 50, 24, 5, a); }},
      {"hexagon", [](cv::Point2d c, double a) { return regular(c, 45, 6, a); }},
      {"disc", [](cv::Point2d c, double a) { return ellipse(c, 42, 42, a); }},
  };
}

bool profile_of(const Poly& p, double angle_noise_seed, std::vector<double>& profile, DetectedObject& obj) {
  Scene s;
  s.noise_sigma = 3;
  s.blur_sigma = 0.8;
  s.seed = unsigned(angle_noise_seed);
  Detection det;
  std::string err;
  if (!detect(to_gray8(render(s, {p})), cv::Mat(), {}, nullptr, det, err) || det.objects.size() != 1) return false;
  profile = det.profiles[0];
  obj = det.objects[0];
  return true;
}

Library teach_all(bool mirror_ok_for_ell) {
  Library lib;
  int seed = 100;
  for (const Class& c : classes()) {
    std::vector<double> prof;
    DetectedObject o;
    EXPECT_TRUE(profile_of(c.make({320, 240}, 0), seed++, prof, o)) << c.name;
    LibraryEntry e;
    e.name = c.name;
    e.profile = prof;
    e.area_px = o.geometry.half_area_px;
    e.area_kind = AreaKind::HalfLevel;
    e.elongation = o.pose.elongation;
    e.mirror_ok = mirror_ok_for_ell && std::string(c.name) == "ell";
    upsert(lib, e);
  }
  return lib;
}

TEST(Identify, NineClassesAtRandomPoses) {
  Library lib = teach_all(false);
  ASSERT_EQ(lib.entries.size(), 9u);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0, 1);
  int right = 0, total = 0;
  for (int rep = 0; rep < 6; ++rep) {
    for (const Class& c : classes()) {
      std::vector<double> prof;
      DetectedObject o;
      cv::Point2d centre(200 + 240 * U(rng), 150 + 180 * U(rng));
      double angle = 360 * U(rng);  // includes turns by 180 degrees
      ASSERT_TRUE(profile_of(c.make(centre, angle), 1000 + total, prof, o));
      Match m = identify(lib, prof, SeenArea::of(o.geometry, 0), o.pose.elongation, {});
      bool ok = m.entry >= 0 && lib.entries[size_t(m.entry)].name == std::string(c.name) && m.score >= 0.5;
      if (!ok) std::printf("%s at %.1f deg -> %s (%.3f)\n", c.name, angle, m.entry >= 0 ? lib.entries[size_t(m.entry)].name.c_str() : "-", m.score);
      right += ok;
      ++total;
    }
  }
  std::printf("identified %d of %d\n", right, total);
  EXPECT_EQ(right, total);
}

TEST(Identify, TurnedBy180DegreesMatchesWithHighScore) {
  Library lib = teach_all(false);
  std::vector<double> a, b;
  DetectedObject oa, ob;
  ASSERT_TRUE(profile_of(l_shape({320, 240}, 90, 30, 25), 7, a, oa));
  ASSERT_TRUE(profile_of(l_shape({320, 240}, 90, 30, 205), 8, b, ob));
  Match ma = identify(lib, a, SeenArea::of(oa.geometry, 0), oa.pose.elongation, {});
  Match mb = identify(lib, b, SeenArea::of(ob.geometry, 0), ob.pose.elongation, {});
  EXPECT_EQ(lib.entries[size_t(ma.entry)].name, "ell");
  EXPECT_EQ(lib.entries[size_t(mb.entry)].name, "ell");
  EXPECT_GT(mb.score, 0.8);
}

TEST(Identify, MirrorImageIsUnknownUnlessTheEntryAllowsIt) {
  Library strict;
  Library mirror_ok;
  {
    Library all = teach_all(true);
    for (const auto& e : all.entries) {
      if (e.name != "ell") continue;
      LibraryEntry s = e;
      s.mirror_ok = false;
      strict.entries.push_back(s);
      mirror_ok.entries.push_back(e);
    }
  }
  std::vector<double> prof;
  DetectedObject o;
  ASSERT_TRUE(profile_of(l_shape({300, 250}, 90, 30, 63, true), 9, prof, o));
  Match s = identify(strict, prof, SeenArea::of(o.geometry, 0), o.pose.elongation, {});
  Match m = identify(mirror_ok, prof, SeenArea::of(o.geometry, 0), o.pose.elongation, {});
  std::printf("mirrored ell: strict %.3f, mirror_ok %.3f\n", s.score, m.score);
  EXPECT_LT(s.score, 0.5);
  EXPECT_GT(m.score, 0.8);
}

TEST(Identify, UntaughtShapeIsUnknown) {
  Library lib = teach_all(false);
  std::vector<double> prof;
  DetectedObject o;
  ASSERT_TRUE(profile_of(star({300, 250}, 55, 35, 8, 10), 11, prof, o));  // an 8-pointed star, not taught
  Match m = identify(lib, prof, SeenArea::of(o.geometry, 0), o.pose.elongation, {});
  EXPECT_LT(m.score, 0.5) << lib.entries[size_t(m.entry)].name;
}

TEST(Identify, SameShapeTwiceAsLargeIsNotTheSameObject) {
  Library lib = teach_all(false);
  std::vector<double> prof;
  DetectedObject o;
  ASSERT_TRUE(profile_of(rectangle({320, 240}, 220, 72, 15), 12, prof, o));
  Match m = identify(lib, prof, SeenArea::of(o.geometry, 0), o.pose.elongation, {});
  EXPECT_LT(m.score, 0.5);
}

// The scene generator's catalogue (tools/scenegen/scenegen/shapes.py, cm), which tools/world lays on its table.
std::vector<cv::Point2d> catalogue_cm(const std::string& name) {
  auto ring = [](int n, double a, double b, double start) {
    std::vector<cv::Point2d> v;
    for (int k = 0; k < n; ++k) v.emplace_back(a * std::cos(start + k * 2 * M_PI / n), b * std::sin(start + k * 2 * M_PI / n));
    return v;
  };
  if (name == "l_shape") return {{0, 0}, {0.75, 0}, {0.75, 1.15}, {3.2, 1.15}, {3.2, 1.9}, {0, 1.9}};
  if (name == "l_mirror") return {{0, 1.9}, {-3.2, 1.9}, {-3.2, 1.15}, {-0.75, 1.15}, {-0.75, 0}, {0, 0}};
  if (name == "t_shape") return {{-1.5, 0}, {1.5, 0}, {1.5, 0.75}, {0.4, 0.75}, {0.4, 2.65}, {-0.4, 2.65}, {-0.4, 0.75}, {-1.5, 0.75}};
  if (name == "triangle") return {{0, 0}, {3.3, 0}, {0.9, 1.7}};
  if (name == "rectangle") return {{-1.5, -0.75}, {1.5, -0.75}, {1.5, 0.75}, {-1.5, 0.75}};
  if (name == "ellipse") return ring(256, 1.45, 0.8, 0);
  if (name == "hexagon") return ring(6, 1.25, 1.25, 0);
  if (name == "star") {
    std::vector<cv::Point2d> v;
    for (int k = 0; k < 10; ++k) {
      double r = k % 2 ? 0.62 : 1.45, t = -M_PI / 2 + k * M_PI / 5;
      v.emplace_back(r * std::cos(t), r * std::sin(t));
    }
    return v;
  }
  ADD_FAILURE() << "no class " << name;
  return {};
}

// A class at 40 px/cm, turned by angle and centred (area centroid) on c.
Poly catalogue(const std::string& name, cv::Point2d c, double angle_deg) {
  Poly p;
  for (const auto& v : catalogue_cm(name)) p.push_back(v * 40.0);
  cv::Point2d m = poly_centroid(p);
  double t = angle_deg * M_PI / 180;
  for (auto& v : p) {
    cv::Point2d d = v - m;
    v = c + cv::Point2d(d.x * std::cos(t) - d.y * std::sin(t), d.x * std::sin(t) + d.y * std::cos(t));
  }
  return p;
}

// What a camera 490 mm above the table (principal point pp, 40 px/cm on the table) sees of the prism
// `footprint` x `height_mm`: the footprint, the top face nearer the camera (magnified about pp), the side walls.
std::vector<Poly> seen_from_above(const Poly& footprint, double height_mm, cv::Point2d pp) {
  const double z = 490, k = z / (z - height_mm);
  Poly top;
  for (const auto& v : footprint) top.push_back(pp + (v - pp) * k);
  std::vector<Poly> out{footprint, top};
  for (size_t i = 0; i < footprint.size(); ++i) {
    size_t j = (i + 1) % footprint.size();
    out.push_back({footprint[i], footprint[j], top[j], top[i]});
  }
  return out;
}

// The five classes of tools/world's library, taught flat (as data/demo/teach), in an 800 x 600 frame; learnt:
// with the thresholds learnt from their own views (issue 27), else none (the global 0.5, as data/demo's).
Library world_library(bool learnt = false) {
  Library lib;
  for (const char* name : {"l_shape", "star", "triangle", "rectangle", "ellipse"}) {
    Scene s;
    s.size = {800, 600};
    s.noise_sigma = 2, s.blur_sigma = 0.7, s.seed = 5;
    Detection det;
    std::string err;
    EXPECT_TRUE(detect(to_gray8(render(s, {catalogue(name, {400, 300}, 0)})), cv::Mat(), {}, nullptr, det, err)) << err;
    if (det.objects.size() != 1) {
      ADD_FAILURE() << name << ": " << det.objects.size() << " objects";
      continue;
    }
    LibraryEntry e{name, false, det.profiles[0], det.objects[0].geometry.half_area_px, std::nullopt, AreaKind::HalfLevel,
                   det.objects[0].pose.elongation, std::nullopt};
    if (learnt) e.threshold = learn_threshold(det.objects[0].geometry, e, {}, {}, GripOptions{}.lines).threshold;
    upsert(lib, e);
  }
  return lib;
}

// The class's best match when it stands height_mm tall at (dx, dy) px from the principal point, turned by angle.
Match seen_tall(const Library& lib, const std::string& name, double height_mm, cv::Point2d off, double angle,
                unsigned seed, const MatchOptions& opt = {}) {
  Scene s;
  s.size = {800, 600};
  s.noise_sigma = 2, s.blur_sigma = 0.7, s.seed = seed;
  const cv::Point2d pp(400, 300);
  Detection det;
  std::string err;
  if (!detect(to_gray8(render(s, seen_from_above(catalogue(name, pp + off, angle), height_mm, pp))), cv::Mat(), {},
              nullptr, det, err) ||
      det.objects.size() != 1) {
    ADD_FAILURE() << name << ": not one object (" << err << ")";
    return {};
  }
  return identify(lib, det.profiles[0], SeenArea::of(det.objects[0].geometry, 0), det.objects[0].pose.elongation, opt);
}

// tools/world found the L and the star unknown on its table: the L's centroid lies 1.2 mm from its inner edge, so
// the rays from it graze the inner corner and that edge, and r jumps within a bin as the axis or the centroid moves
// by a fraction of a degree or a millimetre; a tall object seen off the optical axis also looks larger (top face
// nearer, side walls showing). Both are known now, up to 12 mm tall at the view's edge, at any angle.
TEST(Identify, TallObjectsSeenOffTheAxisAreKnown) {
  Library lib = world_library();
  ASSERT_EQ(lib.entries.size(), 5u);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> U(0, 1);
  int right = 0, total = 0, right_before = 0;
  MatchOptions before;  // the comparison without the angle slack and the growth allowance
  before.angle_slack_bins = 0, before.size_grow = 0;
  for (const char* name : {"l_shape", "star", "triangle", "rectangle", "ellipse"}) {
    double lowest = 1, lowest_before = 1;
    const int poses = std::string(name) == "l_shape" ? 24 : 4;
    for (int i = 0; i < poses; ++i) {
      double h = 2 + 10 * U(rng);  // 2 .. 12 mm
      double r = 120 + 200 * U(rng), t = 2 * M_PI * U(rng);  // 30 to 80 mm off the axis, 40 px/cm
      cv::Point2d off(r * std::cos(t), 0.75 * r * std::sin(t));
      double angle = 360 * U(rng);
      Match m = seen_tall(lib, name, h, off, angle, 300 + total);
      Match b = seen_tall(lib, name, h, off, angle, 300 + total, before);
      bool ok = m.entry >= 0 && lib.entries[size_t(m.entry)].name == name && m.score >= 0.5;
      right += ok, right_before += b.entry >= 0 && lib.entries[size_t(b.entry)].name == name && b.score >= 0.5;
      lowest = std::min(lowest, ok ? m.score : 0.0);
      lowest_before = std::min(lowest_before, b.entry >= 0 && lib.entries[size_t(b.entry)].name == name ? b.score : 0.0);
      if (!ok) std::printf("%s %.0f mm tall at %.0f deg -> %s (%.3f)\n", name, h, angle, m.entry >= 0 ? lib.entries[size_t(m.entry)].name.c_str() : "-", m.score);
      ++total;
    }
    std::printf("%-9s lowest score %.3f (without the slack and the allowance %.3f)\n", name, lowest, lowest_before);
  }
  std::printf("known %d of %d (without the slack and the allowance: %d)\n", right, total, right_before);
  EXPECT_EQ(right, total);
}

// Issue 27's trade-off, measured: the same tall objects off the axis against thresholds learnt from flat teach
// images. The views model a flat part seen from above; a tall one far off the axis changes shape beyond them.
TEST(Identify, TallObjectsOffTheAxisAgainstLearntThresholds) {
  Library lib = world_library(true);
  ASSERT_EQ(lib.entries.size(), 5u);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> U(0, 1);
  int known = 0, total = 0, wrong = 0;
  for (const char* name : {"l_shape", "star", "triangle", "rectangle", "ellipse"}) {
    int k = 0;
    for (int i = 0; i < 8; ++i, ++total) {
      double h = 2 + 10 * U(rng), r = 120 + 200 * U(rng), t = 2 * M_PI * U(rng);
      Match m = seen_tall(lib, name, h, {r * std::cos(t), 0.75 * r * std::sin(t)}, 360 * U(rng), 300 + total);
      Identity id = identity_of(lib, m, {});
      k += id.label && *id.label == name;
      wrong += id.label && *id.label != name;
    }
    auto e = std::find_if(lib.entries.begin(), lib.entries.end(), [&](const LibraryEntry& x) { return x.name == name; });
    std::printf("%-9s threshold %.3f: known %d of 8\n", name, e->threshold.value_or(0), k);
    known += k;
  }
  std::printf("tall objects off the axis known %d of %d with learnt thresholds, wrong %d\n", known, total, wrong);
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(known, total - 4);  // 40 of 40 when measured (issue 27); the L can fall to 0.85, under its 0.923
}

// The allowances do not let other objects through: classes the library does not hold, flat or tall, stay
// unknown (the mirror image of the L, a T, a hexagon), and so does a taught shape 1.5 times as large.
TEST(Identify, UntaughtObjectsSeenTallStayUnknown) {
  Library lib = world_library();
  ASSERT_EQ(lib.entries.size(), 5u);
  unsigned seed = 900;
  for (const char* name : {"l_mirror", "t_shape", "hexagon"}) {
    for (double h : {0.0, 12.0}) {
      for (double angle : {0.0, 37.0, 141.0, 250.0}) {
        Match m = seen_tall(lib, name, h, {260, 190}, angle, seed++);
        EXPECT_LT(m.score, 0.5) << name << " " << h << " mm tall at " << angle << " deg: "
                                << lib.entries[size_t(m.entry)].name;
      }
    }
  }
  Library rect_only;
  for (const auto& e : lib.entries)
    if (e.name == "rectangle") rect_only.entries.push_back(e);
  Scene s;
  s.size = {800, 600};
  s.noise_sigma = 2, s.blur_sigma = 0.7;
  Poly big = catalogue("rectangle", {400, 300}, 30);
  for (auto& v : big) v = cv::Point2d(400, 300) + (v - cv::Point2d(400, 300)) * 1.5;
  Detection det;
  std::string err;
  ASSERT_TRUE(detect(to_gray8(render(s, {big})), cv::Mat(), {}, nullptr, det, err)) << err;
  ASSERT_EQ(det.objects.size(), 1u);
  Match m = identify(rect_only, det.profiles[0], SeenArea::of(det.objects[0].geometry, 0), det.objects[0].pose.elongation, {});
  EXPECT_LT(m.score, 0.5);
}

// tools/world's c_ring (radii 13 and 8.5 mm, a 50 degree gap), seen from straight above: taught light grey (teach
// world seed 3005 of `tools/bench/world --classes new --teach`), then black in world seed 1001, the same light.
// It answered object_absent there: 0.918 against its learnt 0.923. Its cast shadow, above the low threshold,
// joined the light ring's component and pulled its median contrast to 90 (its own pixels: 117), so the half level, and
// the outline, lay out in the blur; and the soft layer's sum counted the shadow's faint fraction all round the
// thin ring: the grey ring measured 4992 px, the black one 4712.
TEST(Identify, APartTaughtLightGreyIsKnownWhenBlackUnderTheSameLight) {
  auto one = [](const char* file, DetectedObject& o, std::vector<double>& profile) {
    Detection det;
    std::string err;
    DetectorOptions opt;
    opt.objects = Polarity::Dark;
    const cv::Mat gray = cv::imread(std::string(RBX1_DATA_DIR) + "/world/" + file, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(gray.empty()) << file;
    ASSERT_TRUE(detect(gray, cv::Mat(), opt, nullptr, det, err)) << err;
    ASSERT_EQ(det.objects.size(), 1u) << file;
    o = det.objects[0], profile = det.profiles[0];
  };
  DetectedObject grey, black;
  std::vector<double> taught_profile, seen_profile;
  one("c_ring_light_grey.png", grey, taught_profile);
  one("c_ring_black.png", black, seen_profile);
  std::printf("level %.0f / %.0f, soft layer %.0f / %.0f px, half level %.0f / %.0f px (grey / black)\n",
              grey.layer.level, black.layer.level, grey.geometry.area_px, black.geometry.area_px,
              grey.geometry.half_area_px, black.geometry.half_area_px);
  EXPECT_NEAR(grey.geometry.half_area_px / black.geometry.half_area_px, 1.0, 0.015);
  EXPECT_NEAR(grey.layer.level, 114, 6);

  LibraryEntry e{"c_ring", false, taught_profile, grey.geometry.half_area_px, std::nullopt, AreaKind::HalfLevel,
                 grey.pose.elongation, std::nullopt};
  e.threshold = learn_threshold(grey.geometry, e, {}, {}, GripOptions{}.lines).threshold;
  Library lib;
  lib.entries.push_back(e);
  const Identity id = identity_of(lib, identify(lib, seen_profile, SeenArea::of(black.geometry, 0), black.pose.elongation, {}), {});
  std::printf("the black ring: %.4f against its learnt %.4f\n", id.best_score.value_or(0), id.threshold.value_or(0));
  EXPECT_EQ(id.label.value_or("unknown"), "c_ring");
  EXPECT_GT(id.best_score.value_or(0), 0.98);
}

TEST(Library, RoundTripAndReplaceByName) {
  Library lib = teach_all(false);
  std::string path = ::testing::TempDir() + "/lib_roundtrip.json", error;
  ASSERT_TRUE(save_library(path, lib, error)) << error;
  Library back;
  ASSERT_TRUE(load_library(path, back, error)) << error;
  ASSERT_EQ(back.entries.size(), lib.entries.size());
  EXPECT_EQ(back.entries[4].name, "ell");
  EXPECT_NEAR(back.entries[4].profile[17], lib.entries[4].profile[17], 1e-4);
  LibraryEntry e = back.entries[0];
  e.area_px = 1234;
  upsert(back, e);
  EXPECT_EQ(back.entries.size(), lib.entries.size());
  EXPECT_EQ(back.entries[0].area_px, 1234);
}

TEST(Library, CorruptFilesAreClearErrors) {
  std::string dir = ::testing::TempDir(), error;
  Library lib;
  auto write = [&](const char* name, const char* text) {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  };
  EXPECT_FALSE(load_library(write("bad1.json", "{not json"), lib, error));
  EXPECT_NE(error.find("invalid JSON"), std::string::npos) << error;
  EXPECT_FALSE(load_library(write("bad2.json", "{\"format\":\"other\"}"), lib, error));
  EXPECT_NE(error.find("not a library"), std::string::npos) << error;
  EXPECT_FALSE(load_library(write("bad3.json",
                                  "{\"format\":\"rbx1-vision-library\",\"version\":1,\"bins\":180,"
                                  "\"objects\":[{\"name\":\"x\",\"profile\":[1,2],\"area_px\":5}]}"),
                            lib, error));
  EXPECT_NE(error.find("objects[0].profile"), std::string::npos) << error;
  EXPECT_FALSE(load_library(dir + "/missing.json", lib, error));
  EXPECT_TRUE(load_library(dir + "/missing.json", lib, error, true));
  EXPECT_TRUE(lib.entries.empty());
}

}  // namespace
}  // namespace rbx1::vision
