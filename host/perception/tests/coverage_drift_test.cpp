// coverage_drift_test.cpp - issue 27: objects covering much of the frame are found (or the doubt is said), and a
// frame lit 0.8-1.2x (gain and offset) against its captured background still finds its objects.
#include <gtest/gtest.h>

#include <cmath>

#include "detector.hpp"
#include "image_io.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

// Six dark squares on a white table, of side chosen for `coverage` of a 640x480 frame.
std::vector<Poly> six_squares(double coverage) {
  const double side = std::sqrt(coverage * 640 * 480 / 6);
  std::vector<Poly> p;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) p.push_back(rectangle({110.0 + 210 * c, 125.0 + 230 * r}, side, side, 0));
  return p;
}

Detection run(const cv::Mat& gray, const cv::Mat& bg, Polarity objects) {
  DetectorOptions o;
  o.objects = objects;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(gray, bg, o, nullptr, d, e)) << e;
  return d;
}

TEST(Coverage, DarkObjectsCoveringMuchOfTheFrameAreFound) {
  // Before: all six found at 29.6 % coverage, none from 30.4 % (the squares' class taken for the table).
  Scene s;
  s.background = 225, s.object = 40, s.noise_sigma = 2, s.blur_sigma = 0.8;
  for (double cov : {0.296, 0.304, 0.4, 0.5}) {
    cv::Mat g = to_gray8(render(s, six_squares(cov)));
    Detection dark = run(g, {}, Polarity::Dark);
    EXPECT_EQ(dark.objects.size(), 6u) << cov;
    // Automatic polarity: found, or the doubt is said (never a silent nothing).
    Detection any = run(g, {}, Polarity::Auto);
    EXPECT_TRUE(any.objects.size() == 6u || !any.warnings.empty()) << cov << ": " << any.objects.size();
    EXPECT_EQ(any.objects.size(), 6u) << cov;
  }
}

TEST(Coverage, ALightBoxInADarkFrameIsTheTable) {
  // pca_test1.jpg in outline: a light box (45 % of the frame) inside a dark frame, six dark objects on it. Both
  // classes fit a smooth surface alike and the dark one holds the frame's border, but it is in seven pieces
  // (the frame and the six objects) and the box in one: the box is the table.
  Scene s;
  s.background = 30, s.object = 225, s.noise_sigma = 2, s.blur_sigma = 0.8;
  cv::Mat g = to_gray8(render(s, {rectangle({320, 240}, 480, 288, 0)}));
  Scene objs = s;
  objs.background = 0, objs.object = 195;  // darkens the box by 195 where the objects lie
  std::vector<Poly> polys;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) polys.push_back(ellipse({170.0 + 150 * c, 170.0 + 140 * r}, 45, 20, 30.0 * c));
  cv::Mat shade = to_gray8(render(objs, polys));
  g -= shade;
  Detection d = run(g, {}, Polarity::Auto);
  EXPECT_EQ(d.objects.size(), 6u);
  EXPECT_TRUE(d.warnings.empty());
}

TEST(Coverage, AnUndecidableTableIsSaidNotSilent) {
  // Half the frame dark, half light, both uniform: either could be the table. Automatic polarity says so (in
  // the detection's warnings, `rbx1 detect`'s JSON and stderr); with the polarity given there is no doubt.
  cv::Mat g(480, 640, CV_8U, cv::Scalar(225));
  g(cv::Rect(0, 0, 320, 480)).setTo(40);
  cv::Mat noise(g.size(), CV_16S);
  cv::randn(noise, 0, 2);
  cv::Mat n16;
  g.convertTo(n16, CV_16S);
  n16 += noise;
  n16.convertTo(g, CV_8U);
  Detection any = run(g, {}, Polarity::Auto);
  ASSERT_EQ(any.warnings.size(), 1u);
  EXPECT_NE(any.warnings[0].find("--objects"), std::string::npos);
  EXPECT_TRUE(run(g, {}, Polarity::Dark).warnings.empty());
}

TEST(LightDrift, GainAndOffsetSweepAgainstTheCapturedBackground) {
  // Issue 27 reported 0 objects at 0.95-0.96 of the background's light and 23 detections at 0.97 (frames not
  // kept); this sweep, the generator's and the world's frames found every object at 0.8-1.2 before and after:
  // a guard over the range the README promises, not a reproduction.
  Scene s;
  s.background = 185, s.object = 70, s.noise_sigma = 1.5, s.blur_sigma = 0.8, s.light_gradient = 20;
  std::vector<Poly> polys = {rectangle({150, 140}, 150, 50, 20), ellipse({450, 150}, 60, 40, -30),
                             regular({160, 350}, 45, 6, 0), star({330, 330}, 60, 28, 5, 0),
                             rectangle({500, 360}, 90, 40, 70)};
  cv::Mat bg = to_gray8(render(s, {}));
  s.seed = 2;
  cv::Mat scene = to_gray8(render(s, polys));
  for (double gain = 0.8; gain <= 1.2001; gain += 0.01)
    for (double offset : {-8.0, 0.0, 8.0}) {
      cv::Mat lit;
      scene.convertTo(lit, CV_8U, gain, offset);
      Detection d = run(lit, bg, Polarity::Auto);
      EXPECT_EQ(d.objects.size(), polys.size()) << "gain " << gain << " offset " << offset;
    }
}

}  // namespace
}  // namespace rbx1::vision

namespace rbx1::vision {
namespace {

TEST(LightDrift, AnOverExposedBackgroundStillFindsTheObjects) {
  // A white table over-exposed when the background was captured (255 everywhere, its true level ~285): the
  // light fit had no unsaturated pixel to work on and left the background as it was, so a frame a few per cent
  // darker (its table 228-252) read the whole table as one dark object: 0 objects (before: 0 at 0.85).
  using namespace test;
  Scene s;
  s.background = 255, s.object = 63, s.blur_sigma = 0.8;
  const std::vector<Poly> polys = {ellipse({150, 140}, 40, 40, 0), rectangle({450, 150}, 120, 50, 20),
                                   regular({160, 350}, 45, 6, 0), ellipse({330, 330}, 60, 35, 30),
                                   rectangle({500, 360}, 90, 40, 70)};
  const cv::Mat bg(480, 640, CV_8U, cv::Scalar(255));
  const cv::Mat scene = to_gray8(render(s, polys));
  for (double gain = 0.80; gain <= 0.8801; gain += 0.02) {
    cv::Mat f, noise(scene.size(), CV_32F), lit;
    scene.convertTo(f, CV_32F, 285.0 / 255 * gain);
    cv::randn(noise, 0, 2);
    f += noise;
    f.convertTo(lit, CV_8U);
    DetectorOptions o;
    Detection d;
    std::string e;
    ASSERT_TRUE(detect(lit, bg, o, nullptr, d, e)) << e;
    EXPECT_EQ(d.objects.size(), polys.size()) << "gain " << gain;
  }
}

}  // namespace
}  // namespace rbx1::vision
