// soft_shade_test.cpp - without a captured background, a dark object's soft shadow beside one side (a shelf of
// contrast between its half level and its own, fading softly into the table) is not part of its outline, while
// an object of two tones with a sharp edge all round (a sweet's lit half) keeps its whole outline.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

// Coverage (0..1) of polygons, 8x supersampled.
cv::Mat coverage(const std::vector<Poly>& polys) {
  Scene cover;
  cover.background = 0, cover.object = 255;
  cv::Mat c8, alpha;
  cv::cvtColor(render(cover, polys), c8, cv::COLOR_BGR2GRAY);
  c8.convertTo(alpha, CV_32F, 1.0 / 255);
  return alpha;
}

// A camera's blur and noise on a float grey image.
cv::Mat camera(cv::Mat in) {
  cv::GaussianBlur(in, in, cv::Size(), 1.0);
  cv::Mat noise(in.size(), CV_32F);
  cv::RNG(3).fill(noise, cv::RNG::NORMAL, 0, 2.0);
  cv::Mat out;
  cv::Mat(in + noise).convertTo(out, CV_8U);
  return out;
}

// A dark ellipse (grey 50 on a 170 table) at 30 degrees, its shadow cast 12 px right and 9 px down and blurred
// 3 px: `depth` of the table's light taken away at the shadow's core, so at 0.55 the shade beside the object
// (about 75 levels of contrast against the object's 120) is above the object's half level.
cv::Mat shaded_ellipse(const Poly& obj, double depth) {
  cv::Mat alpha = coverage({obj}), shade;
  cv::warpAffine(alpha, shade, cv::Mat_<double>({2, 3}, {1, 0, 12, 0, 1, 9}), alpha.size());
  cv::GaussianBlur(shade, shade, cv::Size(), 3.0);
  cv::Mat img(alpha.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float a = alpha.at<float>(y, x);
      img.at<float>(y, x) = 170.0f * (1.0f - float(depth) * shade.at<float>(y, x)) * (1 - a) + 50.0f * a;
    }
  return camera(img);
}

Detection run_auto(const cv::Mat& gray, bool soft_shade) {
  DetectorOptions o;
  o.isolation.soft_shade = soft_shade;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(gray, cv::Mat(), o, nullptr, d, e)) << e;
  return d;
}

TEST(SoftShade, ShadowBesideADarkObjectIsNotItsOutline) {
  const Poly obj = ellipse({300, 220}, 45, 30, 30);
  const cv::Mat g = shaded_ellipse(obj, 0.55);
  const double area = M_PI * 45 * 30, chord = min_chord(obj, poly_centroid(obj));
  Detection d = run_auto(g, true);
  ASSERT_EQ(d.objects.size(), 1u);
  const DetectedObject& o = d.objects[0];
  EXPECT_LT(cv::norm(o.geometry.centroid - poly_centroid(obj)), 0.6);
  EXPECT_NEAR(o.geometry.area_px, area, 0.04 * area);
  EXPECT_NEAR(o.pose.orientation_deg, 30, 1.0);
  EXPECT_NEAR(o.grip.opening_px, chord, 1.5);
  // Without the rule the shade is inside the outline: the centre goes towards it, the area grows.
  Detection before = run_auto(g, false);
  ASSERT_EQ(before.objects.size(), 1u);
  EXPECT_GT(cv::norm(before.objects[0].geometry.centroid - poly_centroid(obj)), 2.0);
  EXPECT_GT(before.objects[0].geometry.area_px, 1.15 * area);
}

TEST(SoftShade, AShallowShadowIsLeftAsBefore) {
  // Shade below the object's half level is outside its outline already: the rule changes nothing.
  const Poly obj = ellipse({300, 220}, 45, 30, 30);
  const cv::Mat g = shaded_ellipse(obj, 0.25);
  Detection with = run_auto(g, true), without = run_auto(g, false);
  ASSERT_EQ(with.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_EQ(with.objects[0].geometry.area_px, without.objects[0].geometry.area_px);
  EXPECT_EQ(with.objects[0].geometry.centroid, without.objects[0].geometry.centroid);
}

TEST(SoftShade, TwoTonesWithASharpEdgeStayOneWholeObject) {
  // A disc whose top is a lighter grey (a sweet lit from above, a two-colour part): the lighter half
  // is a shelf of contrast too, but it ends at the object's own sharp edge, not in a penumbra.
  const Poly disc = ellipse({300, 220}, 40, 40, 0);
  const Poly upper = rectangle({300, 180}, 90, 50, 0);  // the top 30 %
  cv::Mat a = coverage({disc}), top = coverage({upper});
  cv::Mat img(a.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float t = top.at<float>(y, x), grey = 40.0f * (1 - t) + 90.0f * t;
      img.at<float>(y, x) = 170.0f * (1 - a.at<float>(y, x)) + grey * a.at<float>(y, x);
    }
  const cv::Mat g = camera(img);
  Detection d = run_auto(g, true), without = run_auto(g, false);
  ASSERT_EQ(d.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_EQ(d.objects[0].geometry.area_px, without.objects[0].geometry.area_px);
  EXPECT_EQ(d.objects[0].geometry.centroid, without.objects[0].geometry.centroid);
  EXPECT_NEAR(d.objects[0].grip.opening_px, 80, 1.5);  // the whole disc, lit top included
}

}  // namespace
}  // namespace rbx1::vision
