// shadow.hpp - cast shadows against a captured colour background: darker by a roughly constant ratio in every
// channel, the background's chromaticity and texture kept, so table in shade rather than an object.
#pragma once
#include <opencv2/core.hpp>

#include "background.hpp"

namespace rbx1::vision {

struct ShadowOptions {
  double min_ratio = 0.35;    // shade darkens the table to between these fractions of its light...
  double max_ratio = 0.92;
  double max_spread = 0.05;   // ...alike in every channel: each channel's ratio within this of the mean ratio
                              // (plus the noise's share, 8 levels over the channel's background level)
  double min_chroma = 30;     // applied only on a coloured background: its median chroma (max - min channel,
                              // on the smoothed background) at least this many levels; on grey, any grey
                              // object darker than the table would pass as shade
};

// frame, background: CV_8UC3 (BGR), same size; light: the change fitted between them on grey
// (compensate_light), applied to the background first. Returns the number of shadow pixels and `mask`
// (CV_8U, 255 = shade; 3x3 opened: isolated pixels and 1-2 px rims are not shade); 0 and an all-zero mask when
// the background is not coloured enough or the images are not 8-bit BGR.
int shadow_mask(const cv::Mat& frame, const cv::Mat& background, const LightFit& light, const ShadowOptions& opt,
                cv::Mat& mask);

}  // namespace rbx1::vision
