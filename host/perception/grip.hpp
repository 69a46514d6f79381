// grip.hpp - picking points (paper step V): D(theta) = r(theta) + r(theta + pi), minimum, with real contacts
// (outermost contour crossings of the closing line) and finger clearance from neighbouring objects.
#pragma once
#include <vector>

#include <opencv2/core.hpp>

#include "types.hpp"

namespace rbx1::vision {

struct GripOptions {
  int lines = 360;               // closing directions sampled over [0, pi) before the local refinement
  double finger_width_px = 0;    // 0: no clearance check
  double finger_depth_px = 0;
};

// Rays from the centroid at 2*lines angles psi_j = j*pi/lines; per ray the outermost and innermost crossings of
// the contour (r >= 0; -1 when the ray meets no contour, e.g. the centroid lies outside the object).
struct RayHits {
  std::vector<double> rmax, rmin;
};
RayHits cast_rays(const Geometry& g, int lines);

// Chord of the line through the centroid at angle phi between its outermost contour crossings: the
// fingers close from outside along that line. t along (cos phi, sin phi); false when the line misses.
bool chord_at(const Geometry& g, double phi, double& tmin, double& tmax);

// The paper's D(theta) on the sampled lines (phi in [0, pi)) and the chosen grip. labels/obstacle (from
// isolation) locate neighbouring objects; own_label is this object's.
Grip choose_grip(const Geometry& g, const RayHits& hits, int own_label, const cv::Mat& labels,
                 const std::vector<uint8_t>& obstacle, const GripOptions& opt, std::vector<double>& phi,
                 std::vector<double>& d);

}  // namespace rbx1::vision
