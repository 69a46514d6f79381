// twins_test.cpp - issue 27, "an untaught look-alike stays unknown": thresholds learnt per entry from the taught
// object's own views, the runner-up and the margin, and the library field that carries the threshold.
#include <gtest/gtest.h>

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

// Near-twin pairs: a bar and one 10 % longer, a block and one with a small notch, a disc and one with a flat.
Poly notched_block(cv::Point2d c, double angle) {
  Poly p{{-45, -28}, {45, -28}, {45, 28}, {22, 28}, {22, 16}, {8, 16}, {8, 28}, {-45, 28}};
  const double t = angle * M_PI / 180;
  for (auto& v : p) v = c + cv::Point2d(v.x * std::cos(t) - v.y * std::sin(t), v.x * std::sin(t) + v.y * std::cos(t));
  return p;
}
Poly flat_disc(cv::Point2d c, double angle) {
  Poly p;
  const double r = 48, t0 = std::acos(38.0 / r), t = angle * M_PI / 180;
  for (int k = 0; k <= 360; ++k) {
    double a = t0 + k * (2 * M_PI - 2 * t0) / 360;
    p.push_back(c + cv::Point2d(r * std::cos(a + t), r * std::sin(a + t)));
  }
  return p;
}

struct Twin {
  const char* name;
  Maker make;
};
const std::vector<std::pair<Twin, Twin>>& pairs() {
  static const std::vector<std::pair<Twin, Twin>> p = {
      {{"bar", [](cv::Point2d c, double a) { return rectangle(c, 110, 36, a); }},
       {"bar_long", [](cv::Point2d c, double a) { return rectangle(c, 121, 36, a); }}},
      {{"block", [](cv::Point2d c, double a) { return rectangle(c, 90, 56, a); }}, {"block_notch", notched_block}},
      {{"disc", [](cv::Point2d c, double a) { return ellipse(c, 48, 48, a); }}, {"disc_flat", flat_disc}},
  };
  return p;
}

// One object rendered with noise and blur, detected alone.
bool seen(const Poly& p, unsigned seed, Detection& det) {
  Scene s;
  s.noise_sigma = 3, s.blur_sigma = 0.8, s.seed = seed;
  std::string err;
  return detect(to_gray8(render(s, {p})), cv::Mat(), {}, nullptr, det, err) && det.objects.size() == 1;
}

// The entry rbx1 teach makes (Vision::teach_entry): profile, size, and the threshold from its own views.
LibraryEntry taught(const Twin& t, SelfViews* views = nullptr) {
  Detection det;
  EXPECT_TRUE(seen(t.make({320, 240}, 0), 77, det)) << t.name;
  LibraryEntry e;
  e.name = t.name;
  e.profile = det.profiles[0];
  e.area_px = det.objects[0].geometry.half_area_px;
  e.area_kind = AreaKind::HalfLevel;
  e.elongation = det.objects[0].pose.elongation;
  SelfViews v = learn_threshold(det.objects[0].geometry, e, {}, {}, GripOptions{}.lines);
  e.threshold = v.threshold;
  if (views) *views = v;
  return e;
}

// The identity of t at a random pose against lib.
Identity identity_at(const Library& lib, const Twin& t, std::mt19937& rng, unsigned seed, Match* match = nullptr) {
  std::uniform_real_distribution<double> U(0, 1);
  Detection det;
  if (!seen(t.make({200 + 240 * U(rng), 150 + 180 * U(rng)}, 360 * U(rng)), seed, det)) {
    ADD_FAILURE() << t.name << ": not one object";
    return {};
  }
  Match m = identify(lib, det.profiles[0], SeenArea::of(det.objects[0].geometry, 0), det.objects[0].pose.elongation, {});
  if (match) *match = m;
  return identity_of(lib, m, {});
}

TEST(Twins, OwnViewsGiveAThresholdAboveTheGlobalOne) {
  for (const auto& [a, b] : pairs()) {
    for (const Twin* t : {&a, &b}) {
      SelfViews v;
      LibraryEntry e = taught(*t, &v);
      std::printf("%-11s own views %.3f-%.3f, threshold %.3f\n", t->name, v.worst, v.median, v.threshold);
      EXPECT_GT(v.worst, 0.8) << t->name;
      EXPECT_GT(v.threshold, 0.5) << t->name;
      EXPECT_LE(v.threshold, v.worst) << t->name;
      EXPECT_EQ(learn_threshold(Geometry{}, e, {}, {}, 360).threshold, 0.5);  // no contour: the global rule
    }
  }
}

// The defect: with one twin taught, the other scored 0.57-0.83 against it and was taken for it (score >= 0.5).
TEST(Twins, AnUntaughtTwinStaysUnknownAndTheTaughtOneIsKnown) {
  std::mt19937 rng(27);
  unsigned seed = 500;
  int untaught = 0, unknown = 0, over_half = 0, known = 0, taught_seen = 0;
  for (const auto& [a, b] : pairs()) {
    for (bool first : {true, false}) {
      const Twin& teach = first ? a : b;
      const Twin& other = first ? b : a;
      Library lib;
      lib.entries.push_back(taught(teach));
      for (int i = 0; i < 4; ++i) {
        Match m;
        Identity id = identity_at(lib, other, rng, seed++, &m);
        ++untaught;
        unknown += !id.label;
        over_half += m.score >= 0.5;
        EXPECT_FALSE(id.label) << other.name << " taken for " << teach.name << " at " << m.score;
        if (!id.label) {
          EXPECT_EQ(id.verdict, Verdict::BelowThreshold);
          EXPECT_EQ(*id.best, teach.name);
        }
        Identity self = identity_at(lib, teach, rng, seed++);
        ++taught_seen;
        known += self.label && *self.label == teach.name;
        EXPECT_TRUE(self.label) << teach.name << " unknown at " << self.best_score.value_or(0) << " < "
                                << self.threshold.value_or(0);
      }
    }
  }
  std::printf("untaught twins unknown %d of %d (%d scored 0.5 or more: today's rule took them); taught known %d of %d\n",
              unknown, untaught, over_half, known, taught_seen);
  EXPECT_GT(over_half, untaught / 2);  // the pairs are look-alikes: the global rule fails on them
}

// Teaching a second name for an object already in the library made twins silently (issue 27): the same object
// seen again (another pose, noise drawn apart) under a new name is a look-alike of its entry, ambiguous; each
// near-twin pair's other member and an unrelated shape are not (their scores stay under the thresholds).
TEST(Twins, TeachingASecondNameForAKnownObjectIsALookalike) {
  std::mt19937 rng(29);
  for (const auto& [a, b] : pairs()) {
    Library lib;
    lib.entries.push_back(taught(a));
    Detection det;
    ASSERT_TRUE(seen(a.make({260, 210}, 40 + 360 * std::uniform_real_distribution<double>(0, 1)(rng)), 900, det));
    LibraryEntry again;
    again.name = std::string(a.name) + "_again";
    again.profile = det.profiles[0];
    again.area_px = det.objects[0].geometry.half_area_px;
  again.area_kind = AreaKind::HalfLevel;
    again.elongation = det.objects[0].pose.elongation;
    again.threshold = learn_threshold(det.objects[0].geometry, again, {}, {}, GripOptions{}.lines).threshold;
    const std::vector<Lookalike> l = lookalikes(lib, again, {});
    ASSERT_EQ(l.size(), 1u) << a.name;
    EXPECT_EQ(l[0].name, a.name);
    EXPECT_TRUE(l[0].ambiguous) << a.name << " " << l[0].score;
    EXPECT_GE(l[0].score, *lib.entries[0].threshold);
    const std::string w = lookalike_warning(again.name, l[0]);
    EXPECT_NE(w.find("\"" + again.name + "\" looks like \"" + a.name + "\""), std::string::npos) << w;
    EXPECT_NE(w.find("will answer unknown (ambiguous) for both"), std::string::npos) << w;
    EXPECT_TRUE(lookalikes(lib, taught(b), {}).empty()) << b.name << " is not " << a.name;
    LibraryEntry same_name = again;
    same_name.name = a.name;  // taught again under its own name: replaced, no twin
    EXPECT_TRUE(lookalikes(lib, same_name, {}).empty());
  }
  Library lib;
  lib.entries.push_back(taught(pairs()[0].first));
  EXPECT_TRUE(lookalikes(lib, taught(pairs()[2].first), {}).empty());  // a disc is no bar
}

TEST(Twins, BothTaughtEachIsItselfWithTheOtherAsRunnerUp) {
  std::mt19937 rng(28);
  unsigned seed = 700;
  for (const auto& [a, b] : pairs()) {
    Library lib;
    lib.entries.push_back(taught(a));
    lib.entries.push_back(taught(b));
    for (const Twin* t : {&a, &b}) {
      for (int i = 0; i < 3; ++i) {
        Identity id = identity_at(lib, *t, rng, seed++);
        ASSERT_TRUE(id.label) << t->name << " " << verdict_name(id.verdict) << " " << id.best_score.value_or(0);
        EXPECT_EQ(*id.label, t->name);
        ASSERT_TRUE(id.runner_up);
        EXPECT_EQ(*id.runner_up, t == &a ? b.name : a.name);
        EXPECT_LT(*id.runner_up_score, *id.best_score);
      }
    }
  }
}

TEST(Twins, TwoEntriesAcceptingAlikeAreAmbiguous) {
  Library lib;
  lib.entries.resize(3);
  lib.entries[0].name = "a", lib.entries[0].threshold = 0.8;
  lib.entries[1].name = "b", lib.entries[1].threshold = 0.8;
  lib.entries[2].name = "old";  // taught before issue 27: the global threshold
  MatchOptions opt;
  auto verdict = [&](int e, double s, int r, double rs) { return judge(lib, {e, s, r, rs}, opt); };
  EXPECT_EQ(verdict(0, 0.95, 1, 0.93), Verdict::Ambiguous);       // both accept, 0.02 apart
  EXPECT_EQ(verdict(0, 0.95, 1, 0.85), Verdict::Known);           // both accept, 0.10 apart
  EXPECT_EQ(verdict(0, 0.95, 1, 0.79), Verdict::Known);           // the runner-up does not accept
  EXPECT_EQ(verdict(0, 0.79, 1, 0.60), Verdict::BelowThreshold);  // its own threshold, not the global 0.5
  EXPECT_EQ(verdict(2, 0.55, 0, 0.40), Verdict::Known);           // an old entry: 0.5
  EXPECT_EQ(verdict(2, 0.49, 0, 0.40), Verdict::BelowThreshold);
  EXPECT_EQ(verdict(-1, 0, -1, 0), Verdict::NoLibrary);
  opt.threshold = 0.9;  // a global threshold above an entry's own raises it
  EXPECT_EQ(verdict(0, 0.85, -1, 0), Verdict::BelowThreshold);
  Identity id = identity_of(lib, {0, 0.95, 1, 0.93}, MatchOptions{});
  EXPECT_FALSE(id.label);
  EXPECT_EQ(*id.best, "a");
  EXPECT_EQ(*id.runner_up, "b");
  EXPECT_DOUBLE_EQ(*id.threshold, 0.8);
  EXPECT_EQ(std::string(verdict_name(id.verdict)), "ambiguous");
}

TEST(Twins, LibraryCarriesTheThresholdAndOldEntriesLoad) {
  std::string dir = ::testing::TempDir(), error;
  Library lib;
  lib.entries.resize(2);
  for (auto& e : lib.entries) e.profile.assign(kProfileBins, 0.5), e.area_px = 100;
  lib.entries[0].name = "new", lib.entries[0].threshold = 0.91234, lib.entries[0].area_kind = AreaKind::HalfLevel;
  lib.entries[1].name = "old";
  ASSERT_TRUE(save_library(dir + "/twins_lib.json", lib, error)) << error;
  Library back;
  ASSERT_TRUE(load_library(dir + "/twins_lib.json", back, error)) << error;
  ASSERT_EQ(back.entries.size(), 2u);
  ASSERT_TRUE(back.entries[0].threshold);
  EXPECT_DOUBLE_EQ(*back.entries[0].threshold, 0.9123);
  EXPECT_FALSE(back.entries[1].threshold);
  EXPECT_DOUBLE_EQ(entry_threshold(back.entries[1], {}), 0.5);
  EXPECT_EQ(back.entries[0].area_kind, AreaKind::HalfLevel);
  EXPECT_EQ(back.entries[1].area_kind, AreaKind::Layer);
  auto write = [&](const char* name, const std::string& threshold) {
    std::string profile = "[";
    for (int i = 0; i < kProfileBins; ++i) profile += (i ? ",1" : "1");
    std::ofstream(dir + "/" + name) << "{\"format\":\"rbx1-vision-library\",\"version\":1,\"bins\":180,\"objects\":"
                                       "[{\"name\":\"x\",\"area_px\":5,\"profile\":" + profile + "]" + threshold + "}]}";
    return dir + "/" + name;
  };
  EXPECT_TRUE(load_library(write("old.json", ""), back, error)) << error;  // an old library: no threshold field
  EXPECT_FALSE(back.entries[0].threshold);
  EXPECT_EQ(back.entries[0].area_kind, AreaKind::Layer);  // and no area field: the layer's sum
  EXPECT_FALSE(load_library(write("bad.json", ",\"area\":\"soft\""), back, error));
  EXPECT_NE(error.find("objects[0].area must be \"half_level\" or \"layer\""), std::string::npos) << error;
  for (const char* bad : {",\"threshold\":1.5", ",\"threshold\":0", ",\"threshold\":\"high\""}) {
    EXPECT_FALSE(load_library(write("bad.json", bad), back, error)) << bad;
    EXPECT_NE(error.find("objects[0].threshold must be a number in (0, 1]"), std::string::npos) << error;
  }
}

// An entry taught before the half level's area (its profile and size by the layer's sum) still matches its own
// object perfectly: the seen profile is rescaled to that area.
TEST(Twins, AnEntryOfTheLayersAreaMatchesAsBefore) {
  Detection det;
  ASSERT_TRUE(seen(pairs()[0].first.make({300, 220}, 25), 5, det));
  const DetectedObject& o = det.objects[0];
  LibraryEntry old{"old", false, det.profiles[0], o.geometry.area_px, std::nullopt, AreaKind::Layer, o.pose.elongation,
                   std::nullopt};
  for (double& v : old.profile) v *= std::sqrt(o.geometry.half_area_px / o.geometry.area_px);
  Library lib;
  lib.entries.push_back(old);
  EXPECT_NEAR(identify(lib, det.profiles[0], SeenArea::of(o.geometry, 0), o.pose.elongation, {}).score, 1.0, 1e-9);
  EXPECT_NE(o.geometry.half_area_px, o.geometry.area_px);  // the two areas differ: the rescale is what matched it
}

}  // namespace
}  // namespace rbx1::vision
