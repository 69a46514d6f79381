// shadow_test.cpp - a cast shadow on a coloured, textured table is table, not object: darker by one ratio in
// every channel with the table's texture kept; on a grey table the test stands aside.
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
  EXPECT_LT(cv::norm(o.geometry.centroid - truth), 1.0);
  EXPECT_NEAR(o.geometry.area_px, 120 * 40, 0.05 * 120 * 40);
  EXPECT_NEAR(o.pose.orientation_deg, 20, 0.5);
  EXPECT_NEAR(o.grip.opening_px, 40, 1.5);
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

}  // namespace
}  // namespace rbx1::vision
