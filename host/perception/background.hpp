// background.hpp - the contrast image: the frame minus a known or automatically modelled background.
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "types.hpp"

namespace rbx1::vision {

// Kept as the two 8-bit images: the full-frame difference is only ever needed inside object ROIs.
struct Contrast {
  cv::Mat gray, background;  // CV_8U, same size
  int sign = -1;             // -1: objects darker than the background, +1: lighter, 0: both (auto)
  double noise_sigma = 1;    // robust spread of the difference over the table (noise plus pattern residue)
  bool global_model = false; // automatic background: one smooth surface fitted to the table class (bimodal)
  bool modelled = false;     // the background was modelled from the frame (no captured empty table)
  std::string note;          // why the model may be wrong (empty when it is not in doubt)
};

// The background the paper assumes, captured for real: the per-pixel mean of several frames of the empty
// scene (same size and type; 8- or 16-bit, 1, 3 or 4 channels), which averages the sensor noise down by
// sqrt(n). out has the frames' type. false + error "frame K is WxH, frame 1 is WxH" (or empty list/frame).
bool average_background(const std::vector<cv::Mat>& frames, cv::Mat& out, std::string& error);

// Light change between the background's capture and the scene: scene ~= gain * background + offset on the
// pixels that did not change (fitted robustly on a sparse grid, objects and shadows rejected as outliers).
struct LightFit {
  double gain = 1, offset = 0;
  double unchanged = 1;  // fraction of the grid used in the final fit
};
// Fits the light change on 8-bit gray images of the same size; `corrected` (optional) receives the background
// brought to the scene's light (8-bit, saturated; with no change, the background itself, shared: read it only).
// A uniform table fits the gain alone; an implausible change (gain outside 0.5-2, offset beyond 64 levels, under
// 20 % of the table unchanged) returns gain 1, offset 0.
LightFit compensate_light(const cv::Mat& gray, const cv::Mat& background_gray, cv::Mat* corrected);

// The k-th smallest (from 0) of non-negative floats (the fit's residuals), as std::nth_element finds it.
float kth_smallest(const std::vector<float>& v, size_t k);

// Known background (an image of the empty scene, same size). false + error when the sizes differ.
bool contrast_from_background(const cv::Mat& gray, const cv::Mat& background_gray, Polarity objects, double min_contrast,
                              Contrast& out, std::string& error);
// No background image: the background is modelled from the frame itself. When the grey histogram is bimodal
// and a smooth surface (quadratic in x, y) fits the table class closely, that surface is the background (a
// global threshold in effect: crowded trays and large objects stay whole). Otherwise a local model follows
// uneven light or a pattern finer than the objects, objects masked out of the estimate on a second pass.
void contrast_auto(const cv::Mat& gray, Polarity objects, double min_contrast, Contrast& out);

}  // namespace rbx1::vision
