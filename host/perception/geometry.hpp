// geometry.hpp - object geometry (paper step II): edge points by |G| (Eq. 1-2), centroid, r-theta profile (Eq. 3-4).
#pragma once
#include "types.hpp"

namespace rbx1::vision {

inline constexpr double kEdgeThreshold = 0.1;  // t of the paper: |G| of the soft layer, per pixel (a step is 0.5)

// Centroid and second moments of the soft layer; the outer contour's edge pixels (|G| > t) moved along the
// gradient to the layer's half level (sub-pixel); the r-theta profile of those points. false if no edge.
bool measure_geometry(const Layer& layer, Geometry& out);

// Bilinear sample of a CV_32F image (clamped at the border).
float sample(const cv::Mat& img, double x, double y);

}  // namespace rbx1::vision
