// isolate.hpp - object isolation (paper step I): threshold the contrast, clean, region-grow, one layer per object.
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "background.hpp"
#include "components.hpp"
#include "split.hpp"
#include "types.hpp"

namespace rbx1::vision {

struct IsolationOptions {
  double min_contrast = 12;      // grey levels; the threshold is max(this, noise_k * noise sigma)
  double noise_k = 4.5;
  double hysteresis = 0.5;       // regions grow from the threshold down to this fraction of it (hysteresis)
  int min_area_px = 40;          // smaller regions are specks
  double max_foreground = 0.80;  // a larger foreground fraction means a wrong background or no table in view
  int margin_px = 4;             // ROI margin around each object (covers the blurred edge band)
  bool split_touching = true;    // cut touching objects apart at their necks
  double fringe_ratio = 1.5;     // a region attached to an object of the other polarity with this many times
                                 // its contrast is that object's shadow or glare, not an object; so is one of
                                 // its own polarity with at most a quarter of its area (a soft shade)
  bool soft_shade = true;        // without a captured background, a dark object's soft shadow beside it (a shelf
                                 // of contrast between its half level and its own) is taken out of its outline
  SplitOptions split;
};

struct Isolation {
  cv::Mat labels;                 // CV_32S frame: 0 background, else a connected region's id
  std::vector<uint8_t> obstacle;  // per label: 1 when the region is big enough to block a finger
  std::vector<int8_t> sign;       // per label: -1 darker than the background, +1 lighter
  std::vector<Layer> layers;      // the kept objects, in detection order (top to bottom, left to right)
  double threshold = 0;
  int specks = 0, border = 0;     // regions dropped
  int fringes = 0;                // faint regions attached to an object: its shadow, glare or shade
};

// The levels a polarity is labelled at (label_components' low and high): the hysteresis' low level and the
// threshold, max(min_contrast, noise_k * noise sigma), as 8-bit contrasts.
void isolation_levels(const Contrast& contrast, const IsolationOptions& opt, int& low, int& high);

// false + error only for a frame that is nearly all foreground. dark (optional): the dark polarity already
// labelled by the caller (grey_shade_mask's pass on the same images); used when its levels are
// isolation_levels', from label 1 into a zeroed frame (label_frame, no `clear`), else the polarity is labelled
// here. The labels go into label_frame's frame, each region's box noted as written.
bool isolate(const Contrast& contrast, const IsolationOptions& opt, Isolation& out, std::string& error,
             const Labelling* dark = nullptr);

}  // namespace rbx1::vision
