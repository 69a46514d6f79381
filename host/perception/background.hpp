// background.hpp - the contrast image: the frame minus a known or automatically modelled background.
#pragma once
#include <string>

#include <opencv2/core.hpp>

#include "types.hpp"

namespace rbx1::vision {

// Kept as the two 8-bit images: the full-frame difference is only ever needed inside object ROIs.
struct Contrast {
  cv::Mat gray, background;  // CV_8U, same size
  int sign = -1;             // -1: objects darker than the background, +1: lighter
  double noise_sigma = 1;    // robust spread of the difference over the table (noise plus pattern residue)
  // sign * (gray - background) over roi, CV_16S: the objects' contrast, positive.
  cv::Mat contrast(cv::Rect roi) const;
  // 255 where the contrast exceeds t (8-bit saturating arithmetic, full frame).
  cv::Mat above(double t) const;
};

// Known background (an image of the empty scene, same size). false + error when the sizes differ.
bool contrast_from_background(const cv::Mat& gray, const cv::Mat& background_gray, Polarity objects, double min_contrast,
                              Contrast& out, std::string& error);
// No background image: a smooth background is modelled from the frame itself (uniform, uneven light, or a
// pattern finer than the objects), objects masked out of the estimate on a second pass.
void contrast_auto(const cv::Mat& gray, Polarity objects, double min_contrast, Contrast& out);

}  // namespace rbx1::vision
