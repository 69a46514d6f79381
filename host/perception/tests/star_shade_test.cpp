// star_shade_test.cpp - without a captured background, a thin dark star's soft shadow, swept between its arms,
// can be larger than the star itself (tools/world's sil_star_2 seen from above: 7202 px of shade beside 5929 of
// star): its outline is the star's, not the star with the shade in its wedges.
#include <cstdio>
#include <gtest/gtest.h>

#include <algorithm>
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

// A camera's 1 px blur and noise on a float grey image.
cv::Mat camera(cv::Mat img) {
  cv::GaussianBlur(img, img, cv::Size(), 1.0);
  cv::Mat noise(img.size(), CV_32F);
  cv::RNG(5).fill(noise, cv::RNG::NORMAL, 0, 1.5);
  cv::Mat out;
  cv::Mat(img + noise).convertTo(out, CV_8U);
  return out;
}

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
  cv::Mat img(alpha.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float a = alpha.at<float>(y, x);
      img.at<float>(y, x) = 190.0f * (1.0f - float(depth) * shade.at<float>(y, x)) * (1 - a) + 41.0f * a;
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
// the outline took the star with its shade: 7112 and 9978 px for 5562 here; the object's own level (the median
// above half the plain one) alone leaves 5926 and 7745 px.
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
    EXPECT_GT(before.objects[0].geometry.area_px, (depth > 0.2 ? 1.2 : 1.05) * area);
  }
}

// A grey plate (contrast 60) with a black centre (149): the plate outnumbers the centre and lies under its half
// level, like the star's shade, but its edge is the camera's sharp one, not a penumbra: one whole object.
TEST(StarShade, AGreyPlateWithABlackCentreStaysWhole) {
  const Poly plate = ellipse({320, 240}, 60, 60, 0), centre = ellipse({320, 240}, 25, 25, 0);
  const cv::Mat a = coverage({plate}), c = coverage({centre});
  cv::Mat img(a.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float t = c.at<float>(y, x), grey = 130.0f * (1 - t) + 41.0f * t;
      img.at<float>(y, x) = 190.0f * (1 - a.at<float>(y, x)) + grey * a.at<float>(y, x);
    }
  const cv::Mat g = camera(img);
  Detection d = run_auto(g, true), without = run_auto(g, false);
  ASSERT_EQ(d.objects.size(), 1u);
  ASSERT_EQ(without.objects.size(), 1u);
  EXPECT_EQ(d.objects[0].geometry.area_px, without.objects[0].geometry.area_px);
  EXPECT_NEAR(d.objects[0].geometry.area_px, M_PI * 60 * 60, 0.03 * M_PI * 60 * 60);
}

}  // namespace
}  // namespace rbx1::vision
