// background_test.cpp - the captured background: averaging frames, fitting the light change, using both.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include <opencv2/imgproc.hpp>

#include "background.hpp"
#include "detector.hpp"
#include "image_io.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

TEST(Background, AveragingFramesDividesTheNoise) {
  Scene s;
  s.noise_sigma = 8;
  std::vector<cv::Mat> frames;
  for (unsigned i = 0; i < 16; ++i) {
    s.seed = 100 + i;
    frames.push_back(render(s, {}));
  }
  cv::Mat avg;
  std::string error;
  ASSERT_TRUE(average_background(frames, avg, error)) << error;
  EXPECT_EQ(avg.type(), frames[0].type());
  cv::Scalar m0, sd0, m1, sd1;
  cv::meanStdDev(frames[0], m0, sd0);
  cv::meanStdDev(avg, m1, sd1);
  EXPECT_NEAR(sd0[0], 8, 1.0);
  EXPECT_LT(sd1[0], 8 / 4.0 + 0.6);  // sqrt(16) = 4, plus rounding to 8 bits
  EXPECT_NEAR(m1[0], 200, 0.5);
}

TEST(Background, AveragingRejectsMixedFrames) {
  std::string error;
  cv::Mat out;
  EXPECT_FALSE(average_background({}, out, error));
  EXPECT_EQ(error, "no frames to average");
  std::vector<cv::Mat> frames = {cv::Mat(10, 20, CV_8UC3), cv::Mat(10, 21, CV_8UC3)};
  EXPECT_FALSE(average_background(frames, out, error));
  EXPECT_EQ(error, "frame 2 is 21x10 with 3 channels, frame 1 is 20x10 with 3");
}

TEST(Background, LightChangeIsFittedOnUnchangedPixels) {
  Scene s;
  s.light_gradient = 60;  // a textured-enough table: gain and offset are both identifiable
  s.background = 150;
  cv::Mat bg = to_gray8(render(s, {}));
  s.noise_sigma = 2;
  cv::Mat scene = to_gray8(render(s, {rectangle({200, 200}, 200, 80, 20), ellipse({450, 300}, 80, 50, 0)}));
  cv::Mat lit;
  scene.convertTo(lit, CV_8U, 1.2, -10);  // the lamp brightened by 20 %, the camera's black level moved
  LightFit f = compensate_light(lit, bg, nullptr);
  EXPECT_NEAR(f.gain, 1.2, 0.02);
  EXPECT_NEAR(f.offset, -10, 3);
  EXPECT_GT(f.unchanged, 0.8);
  EXPECT_LT(f.unchanged, 0.97);  // the objects' pixels were rejected
}

TEST(Background, DetectionSurvivesALightChange) {
  Scene s;
  s.background = 170, s.object = 90, s.noise_sigma = 1.5;
  cv::Mat bg = to_gray8(render(s, {}));
  std::vector<Poly> polys = {rectangle({200, 200}, 160, 50, 20), ellipse({450, 300}, 60, 40, -30)};
  cv::Mat scene = to_gray8(render(s, polys)), darker;
  scene.convertTo(darker, CV_8U, 0.8, 0);  // a cloud: 20 % less light, table now 34 levels darker
  DetectorOptions o;
  o.objects = Polarity::Dark;
  Detection d;
  std::string error;
  const cv::Mat bg_before = bg.clone();
  ASSERT_TRUE(detect(darker, bg, o, nullptr, d, error)) << error;
  EXPECT_EQ(cv::norm(bg, bg_before, cv::NORM_INF), 0);  // the caller's background is left as it was
  EXPECT_NEAR(d.light.gain, 0.8, 0.01);
  ASSERT_EQ(d.objects.size(), 2u);
  EXPECT_NEAR(d.objects[0].pose.orientation_deg, 20, 0.5);
  o.compensate_light = false;  // without the fit the whole table reads as a dark object
  Detection raw;
  EXPECT_FALSE(detect(darker, bg, o, nullptr, raw, error));
  EXPECT_NE(error.find("foreground"), std::string::npos);
}

TEST(Background, KthSmallestEqualsNthElement) {
  // The light fit's median residual: equal to what std::nth_element selects, on residual-like data (many ties,
  // zeros, a long tail, values far apart in exponent) of every size from 1.
  std::mt19937 rng(3);
  for (int trial = 0; trial < 300; ++trial) {
    const size_t n = 1 + rng() % 7000;
    std::vector<float> v(n);
    std::exponential_distribution<float> E(trial % 2 ? 0.5f : 0.01f);
    for (float& f : v) f = rng() % 5 == 0 ? float(rng() % 4) : trial % 3 == 0 ? E(rng) * 1e-6f : E(rng);
    for (size_t k : {size_t(0), n / 2, n - 1, size_t(rng() % n)}) {
      std::vector<float> w = v;
      std::nth_element(w.begin(), w.begin() + long(k), w.end());
      ASSERT_EQ(kth_smallest(v, k), w[k]) << "n=" << n << " k=" << k;
    }
  }
  EXPECT_EQ(kth_smallest({3.5f, 0.0f, 1.25f}, 1), 1.25f);
}

}  // namespace
}  // namespace rbx1::vision
