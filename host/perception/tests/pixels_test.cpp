// pixels_test.cpp - the fused ROI loops against the OpenCV calls they replace, bit for bit: square dilation,
// whether a 5x5 opening leaves anything, the Sobel gradient and its edge count, the second-order moments.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include <opencv2/imgproc.hpp>

#include "pixels.hpp"

namespace rbx1::vision {
namespace {

// A soft layer like isolation makes: 0 outside, 1 inside, fractions on a blurred edge, noise, and exact zeros
// and ones in runs; also pure noise. Sizes from 1x1 up, odd and even, wider and taller than a 32 px tile.
cv::Mat soft_layer(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat s(h, w, CV_32F, cv::Scalar(0));
  if (seed % 4 == 3) {
    cv::randu(s, -0.5, 1.5);
    return s;
  }
  std::uniform_real_distribution<double> U(0, 1);
  cv::ellipse(s, cv::RotatedRect({float(w * U(rng)), float(h * U(rng))}, {float(w * U(rng)), float(h * U(rng))},
                                 float(360 * U(rng))), cv::Scalar(1), -1, cv::LINE_AA);
  cv::GaussianBlur(s, s, cv::Size(), 0.5 + U(rng));
  cv::Mat n(s.size(), CV_32F);
  cv::randn(n, 0, 0.05);
  s += n;
  cv::min(cv::max(s, 0), 1, s);
  return s;
}

bool same_bits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

TEST(Pixels, DilateSquareEqualsOpenCVDilate) {
  std::mt19937 rng(5);
  for (int i = 0; i < 60; ++i) {
    const int w = 1 + int(rng() % 90), h = 1 + int(rng() % 90), r = i % 10 == 9 ? 8 : int(rng() % 4);
    cv::Mat src(h, w, CV_8U);
    cv::randu(src, 0, 256);
    cv::threshold(src, src, 200 + int(rng() % 50), 255, cv::THRESH_TOZERO);  // sparse, as a mask is
    cv::Mat want, got;
    cv::dilate(src, want, cv::Mat(), cv::Point(-1, -1), r);
    dilate_square(src, got, r);
    ASSERT_TRUE(same_bits(want, got)) << w << "x" << h << " r=" << r;
    cv::Mat in_place = src.clone();
    dilate_square(in_place, in_place, r);
    ASSERT_TRUE(same_bits(want, in_place)) << "in place " << w << "x" << h << " r=" << r;
  }
  // A view into a larger image (a ROI with a row step) works too.
  cv::Mat big(50, 60, CV_8U, cv::Scalar(0)), want, got;
  big.at<uchar>(20, 30) = 255;
  cv::dilate(big(cv::Rect(25, 15, 20, 10)), want, cv::Mat(), cv::Point(-1, -1), 2);
  dilate_square(big(cv::Rect(25, 15, 20, 10)), got, 2);
  EXPECT_TRUE(same_bits(want, got));
  EXPECT_EQ(cv::countNonZero(got), 25);
}

TEST(Pixels, Opening5AnyEqualsOpenCVOpening) {
  // Masks of random blobs, dense and sparse, from 1x1 up: the answer both ways, on borders too.
  std::mt19937 rng(9);
  int fits = 0;
  for (int i = 0; i < 400; ++i) {
    const int w = 1 + int(rng() % 40), h = 1 + int(rng() % 40);
    cv::Mat m(h, w, CV_8U);
    cv::randu(m, 0, 256);
    cv::threshold(m, m, 20 + int(rng() % 60), 255, cv::THRESH_BINARY);
    if (i % 2) cv::dilate(m, m, cv::Mat(), cv::Point(-1, -1), 1 + int(rng() % 2));
    else cv::erode(m, m, cv::Mat(), cv::Point(-1, -1), int(rng() % 2));
    cv::Mat opened;
    cv::morphologyEx(m, opened, cv::MORPH_OPEN, cv::Mat::ones(5, 5, CV_8U));
    const bool want = cv::countNonZero(opened) > 0;
    ASSERT_EQ(opening5_any(m), want) << w << "x" << h << " case " << i;
    fits += want;
  }
  EXPECT_GT(fits, 60);
  EXPECT_LT(fits, 340);
  // A 5x5 square only at a corner, a 4x5 one, an all-clear and an all-set ROI of a larger image.
  cv::Mat big(30, 30, CV_8U, cv::Scalar(0));
  big(cv::Rect(0, 0, 5, 5)).setTo(255);
  EXPECT_TRUE(opening5_any(big));
  big(cv::Rect(0, 0, 5, 5)).setTo(0);
  big(cv::Rect(10, 10, 4, 5)).setTo(255);
  EXPECT_FALSE(opening5_any(big));
  EXPECT_TRUE(opening5_any(big(cv::Rect(10, 10, 4, 5))));  // outside counts as set
  EXPECT_FALSE(opening5_any(big(cv::Rect(20, 20, 8, 8))));
}

TEST(Pixels, SobelGradientEqualsOpenCVSobel) {
  const float t2 = float(0.1 * 0.1);
  int edges = 0;
  for (unsigned seed = 0; seed < 80; ++seed) {
    const int w = seed < 8 ? 1 + int(seed) : 20 + int(seed * 37 % 150), h = seed < 8 ? 1 + int(7 - seed) : 15 + int(seed * 53 % 140);
    const cv::Mat s = soft_layer(w, h, seed);
    cv::Mat wx, wy, gx, gy;
    cv::Sobel(s, wx, CV_32F, 1, 0, 3, 1.0 / 8);
    cv::Sobel(s, wy, CV_32F, 0, 1, 3, 1.0 / 8);
    const int want = cv::countNonZero(wx.mul(wx) + wy.mul(wy) > 0.1 * 0.1);
    const int got = sobel_gradient(s, gx, gy, t2);
    ASSERT_EQ(cv::countNonZero(gx != wx), 0) << w << "x" << h << " seed " << seed;
    ASSERT_EQ(cv::countNonZero(gy != wy), 0) << w << "x" << h << " seed " << seed;
    ASSERT_EQ(got, want) << w << "x" << h << " seed " << seed;
    edges += got;
  }
  EXPECT_GT(edges, 10000);  // the layers have edges to count
}

TEST(Pixels, MomentsEqualOpenCVMoments) {
  for (unsigned seed = 0; seed < 80; ++seed) {
    const int w = seed < 8 ? 1 + int(seed) : 20 + int(seed * 37 % 150), h = seed < 8 ? 1 + int(7 - seed) : 15 + int(seed * 53 % 140);
    if (w == 2) continue;  // cv::moments reads a 2-column float matrix as a list of points (a contour)
    const cv::Mat s = soft_layer(w, h, seed);
    const cv::Moments want = cv::moments(s, false), got = moments_second_order(s);
    // Bit for bit: the same operations in the same order.
    for (auto f : {&cv::Moments::m00, &cv::Moments::m10, &cv::Moments::m01, &cv::Moments::m20, &cv::Moments::m11,
                   &cv::Moments::m02, &cv::Moments::mu20, &cv::Moments::mu11, &cv::Moments::mu02})
      ASSERT_EQ(std::memcmp(&(want.*f), &(got.*f), sizeof(double)), 0)
          << w << "x" << h << " seed " << seed << ": " << want.*f << " vs " << got.*f;
  }
  // A ROI view (row step larger than its width).
  const cv::Mat big = soft_layer(120, 90, 11), roi = big(cv::Rect(7, 5, 70, 61));
  EXPECT_EQ(cv::moments(roi, false).m11, moments_second_order(roi).m11);
  EXPECT_GT(moments_second_order(roi).m00, 100.0);
}

}  // namespace
}  // namespace rbx1::vision
