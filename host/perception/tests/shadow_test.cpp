// shadow_test.cpp - a cast shadow is table, not object: on a coloured, textured table darker by one ratio in
// every channel with the table's texture kept; on a grey table the lighter part of a dark region that lies
// against its darker part and borders the lit table (grey_shade_mask).
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "shadow.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

struct ColourScene {
  cv::Mat frame, background;  // CV_8UC3
  Poly object;
};

// A red bar on a green cloth, its shadow cast 8 px right and 6 px down, `strength` darker; blur and noise as a
// camera's. The object's grey contrast (about 45 levels) is that of the shadow, so on grey alone the shadow
// joins the object.
ColourScene green_cloth(double strength, cv::Vec3f table = {60, 140, 70}) {
  ColourScene s;
  s.object = rectangle({300, 220}, 120, 40, 20);
  Scene cover;
  cover.background = 0, cover.object = 255;
  cv::Mat c8, alpha;
  cv::cvtColor(render(cover, {s.object}), c8, cv::COLOR_BGR2GRAY);
  c8.convertTo(alpha, CV_32F, 1.0 / 255);
  cv::Mat shade;
  cv::warpAffine(alpha, shade, cv::Mat_<double>({2, 3}, {1, 0, 8, 0, 1, 6}), alpha.size());
  cv::GaussianBlur(shade, shade, cv::Size(), 2.0);
  cv::Mat tab(alpha.size(), CV_32FC3), img(alpha.size(), CV_32FC3);
  const cv::Vec3f red(20, 30, 150);
  for (int y = 0; y < tab.rows; ++y)
    for (int x = 0; x < tab.cols; ++x) {
      const float weave = 1.0f + 0.06f * float(std::sin(x * 0.9) * std::sin(y * 0.9));  // cloth texture
      const cv::Vec3f t = table * weave;
      tab.at<cv::Vec3f>(y, x) = t;
      const float a = alpha.at<float>(y, x);
      img.at<cv::Vec3f>(y, x) = t * (1.0f - float(strength) * shade.at<float>(y, x)) * (1 - a) + red * a;
    }
  auto camera = [](cv::Mat in, unsigned seed) {
    cv::GaussianBlur(in, in, cv::Size(), 0.8);
    cv::Mat noise(in.size(), CV_32FC3);
    cv::RNG(seed).fill(noise, cv::RNG::NORMAL, 0, 2.0);
    cv::Mat out;
    cv::Mat(in + noise).convertTo(out, CV_8UC3);
    return out;
  };
  s.frame = camera(img, 1);
  s.background = camera(tab, 2);
  return s;
}

Detection run(const ColourScene& s, bool shadows) {
  DetectorOptions o;
  o.shadows = shadows;
  cv::Mat g, bg;
  cv::cvtColor(s.frame, g, cv::COLOR_BGR2GRAY);
  cv::cvtColor(s.background, bg, cv::COLOR_BGR2GRAY);
  ColourImages colour{s.frame, s.background};
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(g, bg, o, nullptr, d, e, &colour)) << e;
  return d;
}

// The 120x40 bar at 20 degrees both shadow scenes cast: its centre within centre_px of truth, its area within
// area_frac, its orientation within deg, its opening within opening_px.
void expect_bar(const DetectedObject& o, cv::Point2d truth, double centre_px, double area_frac, double deg,
                double opening_px) {
  EXPECT_LT(cv::norm(o.geometry.centroid - truth), centre_px);
  EXPECT_NEAR(o.geometry.area_px, 120 * 40, area_frac * 120 * 40);
  EXPECT_NEAR(o.pose.orientation_deg, 20, deg);
  EXPECT_NEAR(o.grip.opening_px, 40, opening_px);
}

TEST(Shadow, CastShadowOnAColouredClothIsNotObject) {
  const ColourScene s = green_cloth(0.4);
  const cv::Point2d truth = poly_centroid(s.object);
  Detection with = run(s, true), without = run(s, false);
  ASSERT_EQ(with.objects.size(), 1u);
  const DetectedObject& o = with.objects[0];
  // Most of the shadow lies under the bar: what shows is a 3 px band along one long side and a 10 px one at
  // an end (about 750 px).
  EXPECT_GT(with.shadow_px, 500);
  // The pixels where the bar's blurred edge mixes with the shade fail the ratio test (the bar's hue is in
  // them) and stay in the outline: 0.76 px of centre and 3 % of area remain.
  expect_bar(o, truth, 1.0, 0.05, 0.5, 1.5);
  // On grey alone (the test off) the shadow is in the outline: the centre moves 4.9 px towards it.
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_GT(cv::norm(without.objects[0].geometry.centroid - truth), 3.0);
  EXPECT_GT(without.objects[0].geometry.area_px, 1.1 * 120 * 40);
}

TEST(Shadow, NoShadowNoChange) {
  // Without a shadow the test changes nothing that matters: same object, same place.
  const ColourScene s = green_cloth(0.0);
  Detection with = run(s, true), without = run(s, false);
  ASSERT_EQ(with.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_LT(cv::norm(with.objects[0].geometry.centroid - without.objects[0].geometry.centroid), 0.05);
  EXPECT_NEAR(with.objects[0].geometry.area_px, without.objects[0].geometry.area_px, 5);
}

TEST(Shadow, GreyTableIsLeftAlone) {
  // A grey table (chroma under 30 levels): a grey object darker than the table would pass as shade, so the
  // test stands aside and the mask is empty.
  const ColourScene s = green_cloth(0.4, {150, 150, 150});
  cv::Mat mask;
  EXPECT_EQ(shadow_mask(s.frame, s.background, LightFit{}, ShadowOptions{}, mask), 0);
  EXPECT_EQ(cv::countNonZero(mask), 0);
  // Wrong types: no mask, no error.
  cv::Mat g;
  cv::cvtColor(s.frame, g, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(shadow_mask(g, s.background, LightFit{}, ShadowOptions{}, mask), 0);
}

// Grey objects of the given grey levels on a grey table, their shadow cast 8 px right and 6 px down (blurred
// 2 px, `strength` darker), camera blur 0.8 px and noise 2 levels: the scene, its empty table and the objects.
struct GreyScene {
  cv::Mat frame, background;  // CV_8U
  std::vector<Poly> objects;
};

GreyScene grey_table(const std::vector<Poly>& objects, const std::vector<double>& levels, double table,
                     double strength) {
  GreyScene s;
  s.objects = objects;
  cv::Mat all(480, 640, CV_32F, cv::Scalar(0)), img(480, 640, CV_32F, cv::Scalar(0));
  std::vector<cv::Mat> alphas;
  for (const Poly& p : objects) {
    Scene cover;
    cover.background = 0, cover.object = 255;
    cv::Mat c8, a;
    cv::cvtColor(render(cover, {p}), c8, cv::COLOR_BGR2GRAY);
    c8.convertTo(a, CV_32F, 1.0 / 255);
    alphas.push_back(a);
    all = cv::min(all + a, 1.0);
  }
  cv::Mat shade;
  cv::warpAffine(all, shade, cv::Mat_<double>({2, 3}, {1, 0, 8, 0, 1, 6}), all.size());
  cv::GaussianBlur(shade, shade, cv::Size(), 2.0);
  img = table * (1.0 - strength * shade);
  for (size_t i = 0; i < alphas.size(); ++i) img = img.mul(1.0 - alphas[i]) + levels[i] * alphas[i];
  auto camera = [](cv::Mat in, unsigned seed) {
    cv::GaussianBlur(in, in, cv::Size(), 0.8);
    cv::Mat noise(in.size(), CV_32F);
    cv::RNG(seed).fill(noise, cv::RNG::NORMAL, 0, 2.0);
    cv::Mat out;
    cv::Mat(in + noise).convertTo(out, CV_8U);
    return out;
  };
  s.frame = camera(img, 3);
  s.background = camera(cv::Mat(all.size(), CV_32F, cv::Scalar(table)), 4);
  return s;
}

Detection run_grey(const GreyScene& s, bool shadows) {
  DetectorOptions o;
  o.shadows = shadows;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(s.frame, s.background, o, nullptr, d, e)) << e;
  return d;
}

TEST(Shadow, StrongShadowOnAGreyTableIsNotObject) {
  // A dark grey bar (70) on a grey table (180), its shadow 40 % darker (72 levels): more than half the bar's
  // contrast (110), so the half level alone keeps the shade in the outline.
  const GreyScene s = grey_table({rectangle({300, 220}, 120, 40, 20)}, {70}, 180, 0.4);
  const cv::Point2d truth = poly_centroid(s.objects[0]);
  Detection with = run_grey(s, true), without = run_grey(s, false);
  ASSERT_EQ(with.objects.size(), 1u);
  const DetectedObject& o = with.objects[0];
  EXPECT_GT(with.shadow_px, 500);
  expect_bar(o, truth, 0.3, 0.02, 0.3, 1.0);
  // Without the test the shade is in the outline.
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_GT(cv::norm(without.objects[0].geometry.centroid - truth), 2.0);
}

TEST(Shadow, ShadeBetweenTwoGreyObjectsDoesNotJoinThem) {
  // Two dark objects 10 px apart: the left one's shadow (45 % darker) fills the gap, bounded by the lit table
  // only at its ends. Two objects, each where it is.
  const GreyScene s = grey_table({rectangle({250, 240}, 100, 40, 90), rectangle({300, 240}, 100, 40, 90)},
                                 {60, 75}, 190, 0.45);
  Detection d = run_grey(s, true);
  ASSERT_EQ(d.objects.size(), 2u);
  for (const DetectedObject& o : d.objects) {
    const double e0 = cv::norm(o.geometry.centroid - poly_centroid(s.objects[0]));
    const double e1 = cv::norm(o.geometry.centroid - poly_centroid(s.objects[1]));
    EXPECT_LT(std::min(e0, e1), 0.5);
    EXPECT_NEAR(o.geometry.area_px, 100 * 40, 0.03 * 100 * 40);
  }
  // Without the test the shade in the gap stays in the left one's outline.
  double worst = 0;
  for (const DetectedObject& o : run_grey(s, false).objects)
    worst = std::max(worst, std::min(cv::norm(o.geometry.centroid - poly_centroid(s.objects[0])),
                                     cv::norm(o.geometry.centroid - poly_centroid(s.objects[1]))));
  EXPECT_GT(worst, 2.0);
}

TEST(Shadow, GreyObjectWithoutShadowIsNotShade) {
  // A mid-grey disc at the ratio shade has (0.6 of the table) with no shadow: bounded by the table all round,
  // nothing darker against it, so it is an object, whole.
  const GreyScene s = grey_table({ellipse({320, 240}, 50, 30, 10)}, {108}, 180, 0.0);
  cv::Mat mask, shaded;
  EXPECT_EQ(grey_shade_mask(s.frame, s.background, GreyShadeOptions{}, mask, shaded), 0);
  EXPECT_TRUE(mask.empty() && shaded.empty());
  Detection d = run_grey(s, true);
  ASSERT_EQ(d.objects.size(), 1u);
  EXPECT_NEAR(d.objects[0].geometry.area_px, M_PI * 50 * 30, 0.02 * M_PI * 50 * 30);
  // Wrong types: no mask.
  EXPECT_EQ(grey_shade_mask(s.frame, cv::Mat(), GreyShadeOptions{}, mask, shaded), 0);
}

}  // namespace
}  // namespace rbx1::vision
