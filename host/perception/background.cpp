// background.cpp - background subtraction and automatic background modelling, both polarities.
#include "background.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

// Median and MAD-based sigma of gray - background (values within +-255), on a sparse grid for speed.
void robust_stats(const cv::Mat& g, const cv::Mat& bg, int step, double& median, double& sigma) {
  std::array<int, 512> hist{};
  int n = 0;
  for (int y = step / 2; y < g.rows; y += step) {
    const uchar* gr = g.ptr<uchar>(y);
    const uchar* br = bg.ptr<uchar>(y);
    for (int x = step / 2; x < g.cols; x += step) {
      hist[size_t(gr[x] - br[x] + 256)]++;
      ++n;
    }
  }
  auto quantile = [&](const std::array<int, 512>& h, int total) {
    int acc = 0;
    for (int i = 0; i < 512; ++i) {
      acc += h[size_t(i)];
      if (2 * acc >= total) return i - 256;
    }
    return 0;
  };
  int med = quantile(hist, n);
  std::array<int, 512> dev{};
  for (int i = 0; i < 512; ++i) dev[size_t(std::abs(i - 256 - med) + 256)] += hist[size_t(i)];
  int mad = quantile(dev, n);
  median = med;
  sigma = std::max(1.0, 1.4826 * mad);
}

// Which polarity the objects have: the sign whose tail (beyond the threshold) carries more contrast.
int decide_sign(const cv::Mat& g, const cv::Mat& bg, double median, double threshold, int step) {
  double dark = 0, light = 0;
  for (int y = step / 2; y < g.rows; y += step) {
    const uchar* gr = g.ptr<uchar>(y);
    const uchar* br = bg.ptr<uchar>(y);
    for (int x = step / 2; x < g.cols; x += step) {
      double v = gr[x] - br[x] - median;
      if (v < -threshold) dark -= v;
      else if (v > threshold) light += v;
    }
  }
  return light > dark ? +1 : -1;
}

int sign_of(Polarity p) { return p == Polarity::Light ? +1 : -1; }

}  // namespace

cv::Mat Contrast::contrast(cv::Rect roi) const {
  cv::Mat out;
  if (sign > 0) cv::subtract(gray(roi), background(roi), out, cv::noArray(), CV_16S);
  else cv::subtract(background(roi), gray(roi), out, cv::noArray(), CV_16S);
  return out;
}

cv::Mat Contrast::above(double t) const {
  cv::Mat d, out;
  if (sign > 0) cv::subtract(gray, background, d);  // saturates at 0: the other polarity drops out
  else cv::subtract(background, gray, d);
  cv::threshold(d, out, t, 255, cv::THRESH_BINARY);
  return out;
}

bool contrast_from_background(const cv::Mat& gray, const cv::Mat& background_gray, Polarity objects, double min_contrast,
                              Contrast& out, std::string& error) {
  if (gray.size() != background_gray.size()) {
    error = "background is " + std::to_string(background_gray.cols) + "x" + std::to_string(background_gray.rows) +
            " but the frame is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows);
    return false;
  }
  out.gray = gray;
  out.background = background_gray;
  double median = 0;
  robust_stats(gray, background_gray, 3, median, out.noise_sigma);
  out.sign = objects == Polarity::Auto
                 ? decide_sign(gray, background_gray, median, std::max(min_contrast, 4 * out.noise_sigma), 2)
                 : sign_of(objects);
  return true;
}

void contrast_auto(const cv::Mat& gray, Polarity objects, double min_contrast, Contrast& out) {
  // Work at about 160 px across: the background is smooth at that scale, objects are not.
  const int f = std::max(1, int(std::ceil(std::max(gray.cols, gray.rows) / 160.0)));
  cv::Mat small;
  cv::resize(gray, small, cv::Size((gray.cols + f - 1) / f, (gray.rows + f - 1) / f), 0, 0, cv::INTER_AREA);
  int k = std::max(3, (std::min(small.cols, small.rows) / 3) | 1);
  k = std::min(k, 255);
  cv::Mat b0;
  cv::medianBlur(small, b0, k);

  // First guess of the objects at low resolution, to exclude them from the second estimate.
  cv::Mat r;
  cv::subtract(small, b0, r, cv::noArray(), CV_16S);
  double med = 0, sig = 1;
  robust_stats(small, b0, 1, med, sig);
  double t = std::max(min_contrast, 4 * sig);
  int sign = objects == Polarity::Auto ? decide_sign(small, b0, med, t, 1) : sign_of(objects);
  cv::Mat objmask;
  if (sign > 0) cv::compare(r, med + t / 2, objmask, cv::CMP_GT);
  else cv::compare(r, med - t / 2, objmask, cv::CMP_LT);
  cv::dilate(objmask, objmask, cv::Mat(), cv::Point(-1, -1), 1);

  // Normalised convolution: average of background pixels only, with a wide Gaussian.
  cv::Mat w, v, num, den;
  objmask.convertTo(w, CV_32F, -1.0 / 255.0, 1.0);
  small.convertTo(v, CV_32F);
  v = v.mul(w);
  double sigma_blur = std::max(1.0, k / 4.0);
  cv::GaussianBlur(v, num, cv::Size(), sigma_blur);
  cv::GaussianBlur(w, den, cv::Size(), sigma_blur);
  cv::Mat bsmall(small.size(), CV_32F);
  for (int y = 0; y < small.rows; ++y) {
    const float* n = num.ptr<float>(y);
    const float* d = den.ptr<float>(y);
    const uchar* fb = b0.ptr<uchar>(y);
    float* o = bsmall.ptr<float>(y);
    for (int x = 0; x < small.cols; ++x) o[x] = d[x] > 0.05f ? n[x] / d[x] : float(fb[x]);
  }
  cv::Mat s8, b8;
  bsmall.convertTo(s8, CV_8U);
  cv::resize(s8, b8, gray.size(), 0, 0, cv::INTER_LINEAR);
  out.gray = gray;
  out.background = b8;
  double median = 0;
  robust_stats(gray, b8, 4, median, out.noise_sigma);
  out.sign = sign;  // decided on the low-resolution residual, where objects stand out of the noise
}

}  // namespace rbx1::vision
