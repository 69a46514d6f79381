// soft_shade_test.cpp - without a captured background, a dark object's soft shadow beside one side (a shelf of
// contrast between its half level and its own, fading softly into the table) is not part of its outline, nor is a
// shade larger than a thin object (a star's, between its arms), while an object of two tones with a sharp edge all
// round (a sweet's lit half, a grey plate with a black centre) keeps its whole outline.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

// An object of grey `object` (coverage alpha) on a table of grey `table` whose light `shade` (0..1) dims by depth.
cv::Mat shaded(const cv::Mat& alpha, const cv::Mat& shade, double depth, float table, float object) {
  cv::Mat img(alpha.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float a = alpha.at<float>(y, x);
      img.at<float>(y, x) = table * (1.0f - float(depth) * shade.at<float>(y, x)) * (1 - a) + object * a;
    }
  return img;
}

// An object of two greys on a table: `whole` at grey `rest`, where it overlaps `part` at grey `part_grey`.
cv::Mat two_tone(const Poly& whole, const Poly& part, float table, float rest, float part_grey) {
  const cv::Mat a = coverage({whole}), t = coverage({part});
  cv::Mat img(a.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float k = t.at<float>(y, x), grey = rest * (1 - k) + part_grey * k;
      img.at<float>(y, x) = table * (1 - a.at<float>(y, x)) + grey * a.at<float>(y, x);
    }
  return img;
}

// A dark ellipse (grey 50 on a 170 table) at 30 degrees, its shadow cast 12 px right and 9 px down and blurred
// 3 px: `depth` of the table's light taken away at the shadow's core, so at 0.55 the shade beside the object
// (about 75 levels of contrast against the object's 120) is above the object's half level.
cv::Mat shaded_ellipse(const Poly& obj, double depth) {
  cv::Mat alpha = coverage({obj}), shade;
  cv::warpAffine(alpha, shade, cv::Mat_<double>({2, 3}, {1, 0, 12, 0, 1, 9}), alpha.size());
  cv::GaussianBlur(shade, shade, cv::Size(), 3.0);
  return camera(shaded(alpha, shade, depth, 170, 50), 2.0, 3);
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
  const cv::Mat g = camera(two_tone(disc, upper, 170, 40, 90), 2.0, 3);
  Detection d = run_auto(g, true), without = run_auto(g, false);
  ASSERT_EQ(d.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_EQ(d.objects[0].geometry.area_px, without.objects[0].geometry.area_px);
  EXPECT_EQ(d.objects[0].geometry.centroid, without.objects[0].geometry.centroid);
  EXPECT_NEAR(d.objects[0].grip.opening_px, 80, 1.5);  // the whole disc, lit top included
}

// A thin dark star's soft shadow, swept between its arms, can be larger than the star itself (tools/world's
// sil_star_2 seen from above: 7202 px of shade beside 5929 of star): its outline is the star's, not the star with
// the shade in its wedges.

// A 10-armed star (grey 41 on a 190 table, as tools/world renders sil_star_2) and its shadow as the world
// casts it: the footprint swept 10 px left and 12 px up (the light from the bottom right, high) and
// blurred 2 px, `depth` of the table's light taken away; then the camera.
cv::Mat shaded_star(const Poly& obj, double depth) {
  const cv::Mat alpha = coverage({obj});
  cv::Mat shade = cv::Mat::zeros(alpha.size(), CV_32F), moved;
  for (int k = 0; k <= 16; ++k) {
    cv::warpAffine(alpha, moved, cv::Mat_<double>({2, 3}, {1, 0, -10.0 * k / 16, 0, 1, -12.0 * k / 16}), alpha.size());
    shade = cv::max(shade, moved);
  }
  cv::GaussianBlur(shade, shade, cv::Size(), 2.0);
  return camera(shaded(alpha, shade, depth, 190, 41), 1.5, 5);
}

// The shade's pixels (darker than the table by a tenth of its depth, outside the star grown 3 px) inside the
// detected outline, as a fraction of the shade.
double shade_inside(const cv::Mat& gray, const Poly& obj, const DetectedObject& o) {
  std::vector<cv::Point> star_px, outline;
  for (const auto& p : obj) star_px.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
  for (const auto& p : o.geometry.contour) outline.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
  cv::Mat star = cv::Mat::zeros(gray.size(), CV_8U), inside = star.clone();
  cv::fillPoly(star, std::vector<std::vector<cv::Point>>{star_px}, cv::Scalar(255));
  cv::dilate(star, star, cv::getStructuringElement(cv::MORPH_RECT, {7, 7}));
  cv::fillPoly(inside, std::vector<std::vector<cv::Point>>{outline}, cv::Scalar(255));
  const cv::Mat shade = (gray < 175) & ~star;
  return double(cv::countNonZero(shade & inside)) / std::max(1, cv::countNonZero(shade));
}

// The world's light shade (25 levels against the star's 149) and a deeper one (57): both under the star's half
// level, both larger than the star. Before, the region's median lay in the shade (70 here, 30 in the world) and
// the outline took the star with its shade: 7112 and 9978 px for 5562 here.
TEST(StarShade, AShadeLargerThanAThinStarIsNotItsOutline) {
  const Poly obj = star({320, 240}, 75, 24, 10, 9);
  const double area = std::abs(cv::contourArea(std::vector<cv::Point2f>(obj.begin(), obj.end())));
  for (double depth : {0.13, 0.30}) {
    SCOPED_TRACE(depth);
    const cv::Mat g = shaded_star(obj, depth);
    Detection d = run_auto(g, true);
    ASSERT_EQ(d.objects.size(), 1u);
    const DetectedObject& o = d.objects[0];
    EXPECT_NEAR(o.geometry.area_px, area, 0.03 * area);
    EXPECT_LT(cv::norm(o.geometry.centroid - poly_centroid(obj)), 1.0);
    EXPECT_LT(shade_inside(g, obj, o), 0.02);
    // Without the rule the shade is in the outline.
    Detection before = run_auto(g, false);
    ASSERT_EQ(before.objects.size(), 1u);
    std::printf("depth %.2f: %.0f px with the rule, %.0f px without, true %.0f\n", depth, o.geometry.area_px,
                before.objects[0].geometry.area_px, area);
    EXPECT_GT(before.objects[0].geometry.area_px, 1.2 * area);
  }
}

// A grey plate (contrast 60) with a black centre (149): the plate outnumbers the centre and lies under its half
// level, like the star's shade, but its edge is the camera's sharp one, not a penumbra: one whole object.
TEST(StarShade, AGreyPlateWithABlackCentreStaysWhole) {
  const Poly plate = ellipse({320, 240}, 60, 60, 0), centre = ellipse({320, 240}, 25, 25, 0);
  const cv::Mat g = camera(two_tone(plate, centre, 190, 130, 41), 1.5, 5);
  Detection d = run_auto(g, true), without = run_auto(g, false);
  ASSERT_EQ(d.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_EQ(d.objects[0].geometry.area_px, without.objects[0].geometry.area_px);
  EXPECT_NEAR(d.objects[0].geometry.area_px, M_PI * 60 * 60, 0.03 * M_PI * 60 * 60);
}

}  // namespace
}  // namespace rbx1::vision
