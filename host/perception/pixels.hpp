// pixels.hpp - pixel loops over the objects' small ROIs, fused and vectorised (-O3), each equal bit for bit to
// the OpenCV calls it replaces (pixels_test checks every one against them): on ~130x130 ROIs those calls'
// own overhead and their temporaries cost more than the arithmetic.
#pragma once
#include <opencv2/core.hpp>

namespace rbx1::vision {

// cv::dilate(src, dst, cv::Mat(), {-1, -1}, r) (a 3x3 square r times) with its default border: the maximum
// over the (2r+1)-square around each pixel, outside the image ignored. CV_8U; dst may be src.
void dilate_square(const cv::Mat& src, cv::Mat& dst, int r);

// The layer's gradient as cv::Sobel(s, gx, CV_32F, 1, 0, 3, 1.0 / 8) and cv::Sobel(s, gy, CV_32F, 0, 1, 3,
// 1.0 / 8) give it (reflected border), s CV_32F. Returns how many pixels have gx*gx + gy*gy > t2 (in float, as
// countNonZero(gx.mul(gx) + gy.mul(gy) > t2) counts them).
int sobel_gradient(const cv::Mat& s, cv::Mat& gx, cv::Mat& gy, float t2);

// Whether cv::morphologyEx(m, MORPH_OPEN, cv::Mat::ones(5, 5, CV_8U)) (default border) has any set pixel, i.e.
// whether a 5x5 square of set pixels fits in m, pixels outside m counting as set. CV_8U; one pass, no image.
bool opening5_any(const cv::Mat& m);

// cv::moments(s, false) of a CV_32F image, up to the second order: m00, m10, m01, m20, m11, m02 and the central
// mu20, mu11, mu02 (the third-order fields stay 0). (cv::moments reads a 2-column matrix as a contour's points;
// this always reads an image.)
cv::Moments moments_second_order(const cv::Mat& s);

}  // namespace rbx1::vision
