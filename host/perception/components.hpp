// components.hpp - the binary image of one polarity (contrast, 3x3 opening, hysteresis) and its 8-connected
// components, in one streaming pass over the frame and a labelling by runs.
#pragma once
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::vision {

struct Component {
  int area = 0;      // pixels above the low level
  cv::Rect box;      // bounding box
  bool strong = false;  // some pixel above the high level (hysteresis: a region that never is, is not an object)
};

// Components of the pixels whose contrast s * (gray - background) (8-bit, saturated at 0), opened with a 3x3
// square (isolated noise pixels and hairlines dropped), is above `low`; 8-connected. Equal to thresholding
// then opening then cv::connectedComponents (a flat opening commutes with a threshold), labels numbered as
// OpenCV numbers them (by each component's first 2x2 block in raster order). Labels first_label,
// first_label + 1, ... are written into `labels` (CV_32S, the frame's size; without `clear`, other pixels are
// left untouched); comps receives one entry per label. clear: `labels` is allocated to the frame's size when
// it is not already and every other pixel is set to 0 in the same sweep (no separate zero fill). Returns the
// number of pixels above `high` (the cleaned foreground).
long long label_components(const cv::Mat& gray, const cv::Mat& background, int s, int low, int high, int first_label,
                           cv::Mat& labels, std::vector<Component>& comps, bool clear = false);

// Two labellings of the same polarity at different levels from one streamed pass (the contrast and its opening
// computed once): each as label_components above would make it, above_high its return value.
struct Labelling {
  int low = 0, high = 0, first_label = 1;
  cv::Mat* labels = nullptr;
  std::vector<Component>* comps = nullptr;
  bool clear = false;
  long long above_high = 0;  // out
};
void label_components(const cv::Mat& gray, const cv::Mat& background, int s, Labelling* outs, int n_outs);

// A CV_32S frame of zeros to label into (without `clear`). The last one is kept per thread: when nobody else
// holds it any more (the previous detection is gone), it comes back with only the boxes noted as written
// cleared, instead of a new frame zeroed whole (3.7 MB at 1280x720); otherwise a new one is made.
cv::Mat label_frame(cv::Size size);
// Notes that pixels inside `box` of `frame` may have been set (ignored unless frame is the kept one).
void label_frame_written(const cv::Mat& frame, cv::Rect box);

}  // namespace rbx1::vision
