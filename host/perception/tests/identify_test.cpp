// identify_test.cpp - identification against taught profiles: 9 classes, 180-degree turns, mirror images,
// non-star-shaped objects, unknown objects, and the library file (round trip, corrupt files).
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <random>

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
    e.area_px = o.geometry.area_px;
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
      Match m = identify(lib, prof, o.geometry.area_px, std::nullopt, o.pose.elongation, {});
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
  Match ma = identify(lib, a, oa.geometry.area_px, std::nullopt, oa.pose.elongation, {});
  Match mb = identify(lib, b, ob.geometry.area_px, std::nullopt, ob.pose.elongation, {});
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
  Match s = identify(strict, prof, o.geometry.area_px, std::nullopt, o.pose.elongation, {});
  Match m = identify(mirror_ok, prof, o.geometry.area_px, std::nullopt, o.pose.elongation, {});
  std::printf("mirrored ell: strict %.3f, mirror_ok %.3f\n", s.score, m.score);
  EXPECT_LT(s.score, 0.5);
  EXPECT_GT(m.score, 0.8);
}

TEST(Identify, UntaughtShapeIsUnknown) {
  Library lib = teach_all(false);
  std::vector<double> prof;
  DetectedObject o;
  ASSERT_TRUE(profile_of(star({300, 250}, 55, 35, 8, 10), 11, prof, o));  // an 8-pointed star, not taught
  Match m = identify(lib, prof, o.geometry.area_px, std::nullopt, o.pose.elongation, {});
  EXPECT_LT(m.score, 0.5) << lib.entries[size_t(m.entry)].name;
}

TEST(Identify, SameShapeTwiceAsLargeIsNotTheSameObject) {
  Library lib = teach_all(false);
  std::vector<double> prof;
  DetectedObject o;
  ASSERT_TRUE(profile_of(rectangle({320, 240}, 220, 72, 15), 12, prof, o));
  Match m = identify(lib, prof, o.geometry.area_px, std::nullopt, o.pose.elongation, {});
  EXPECT_LT(m.score, 0.5);
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
