// background.hpp - the contrast image: the frame minus a known or automatically modelled background.
#pragma once
#include <string>

#include <opencv2/core.hpp>

#include "types.hpp"

namespace rbx1::vision {

struct Contrast {
  cv::Mat diff;             // CV_16S, frame gray minus background gray
  int sign = -1;            // -1: objects darker than the background, +1: lighter
  double noise_sigma = 1;   // robust spread of diff over the background (noise plus pattern residue)
};

// Known background (an image of the empty scene, same size). false + error when the sizes differ.
bool contrast_from_background(const cv::Mat& gray, const cv::Mat& background_gray, Polarity objects, double min_contrast,
                              Contrast& out, std::string& error);
// No background image: a smooth background is modelled from the frame itself (uniform, uneven light, or a
// pattern finer than the objects), objects masked out of the estimate on a second pass.
void contrast_auto(const cv::Mat& gray, Polarity objects, double min_contrast, Contrast& out);

}  // namespace rbx1::vision
