// shadow.cpp - cast shadows against a coloured background: the per-channel ratio test (frame / background).
#include "shadow.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

// Median chroma (max - min channel) of the background, smoothed so sensor noise adds none.
double median_chroma(const cv::Mat& background) {
  cv::Mat small;
  cv::resize(background, small, cv::Size(), 0.25, 0.25, cv::INTER_AREA);
  int hist[256] = {0};
  for (int y = 0; y < small.rows; ++y) {
    const cv::Vec3b* r = small.ptr<cv::Vec3b>(y);
    for (int x = 0; x < small.cols; ++x) {
      const int hi = std::max({r[x][0], r[x][1], r[x][2]}), lo = std::min({r[x][0], r[x][1], r[x][2]});
      hist[hi - lo]++;
    }
  }
  const int n = int(small.total());
  for (int i = 0, acc = 0; i < 256; ++i)
    if ((acc += hist[i]) * 2 >= n) return i;
  return 0;
}

}  // namespace

int shadow_mask(const cv::Mat& frame, const cv::Mat& background, const LightFit& light, const ShadowOptions& opt,
                cv::Mat& mask) {
  mask = cv::Mat::zeros(frame.size(), CV_8U);
  if (frame.type() != CV_8UC3 || background.type() != CV_8UC3 || frame.size() != background.size()) return 0;
  if (median_chroma(background) < opt.min_chroma) return 0;
  // The background in the scene's light, per channel, and the noise's share of each ratio.
  float lut[256], tol[256];
  for (int v = 0; v < 256; ++v) {
    lut[v] = float(std::max(1.0, light.gain * v + light.offset));
    tol[v] = float(opt.max_spread + 8.0 / lut[v]);
  }
  for (int y = 0; y < frame.rows; ++y) {
    const cv::Vec3b* f = frame.ptr<cv::Vec3b>(y);
    const cv::Vec3b* b = background.ptr<cv::Vec3b>(y);
    uchar* m = mask.ptr<uchar>(y);
    for (int x = 0; x < frame.cols; ++x) {
      const float b0 = lut[b[x][0]], b1 = lut[b[x][1]], b2 = lut[b[x][2]];
      const float r = float(f[x][0] + f[x][1] + f[x][2]) / (b0 + b1 + b2);
      if (r < opt.min_ratio || r > opt.max_ratio) continue;
      const bool alike = std::abs(f[x][0] / b0 - r) <= tol[b[x][0]] && std::abs(f[x][1] / b1 - r) <= tol[b[x][1]] &&
                         std::abs(f[x][2] / b2 - r) <= tol[b[x][2]];
      m[x] = alike ? 255 : 0;
    }
  }
  cv::morphologyEx(mask, mask, cv::MORPH_OPEN, cv::Mat::ones(3, 3, CV_8U));
  return cv::countNonZero(mask);
}

}  // namespace rbx1::vision
