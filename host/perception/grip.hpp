// grip.hpp - picking points (paper step V): D(theta) = r(theta) + r(theta + pi), minimum, with real contacts
// (outermost contour crossings of the closing line), fingers off the object's own outline and clear of neighbours.
#pragma once
#include <vector>

#include <opencv2/core.hpp>

#include "types.hpp"

namespace rbx1::vision {

struct GripOptions {
  int lines = 360;               // closing directions sampled over [0, pi) before the local refinement
  double finger_width_px = 0;    // 0: no clearance check
  double finger_depth_px = 0;
  double min_opening_px = 2;     // narrower chords are not a grip (the fingers would close on an edge or nothing)
  double max_opening_px = 0;     // wider chords do not fit the gripper; 0: no limit
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

// The paper's D(theta) on the sampled lines (phi in [0, pi)) and the chosen grip. A line is a grip only when
// the contour crosses it on both sides of the centroid (real contacts, opening > 0). With a finger size the
// opening is that of fingers centred on the centroid whose faces clear the object's outermost points within
// their width (p1/p2 are the faces, symmetric about the centroid). The narrowest such line
// within [min_opening_px, max_opening_px] whose fingers are clear wins. Otherwise the grip is infeasible with
// its reason: no_contact (no line with contacts on both sides), too_narrow / too_wide (none in range),
// finger_collision (none clear). labels/obstacle (from isolation) locate neighbours; own_label is this object's.
Grip choose_grip(const Geometry& g, const RayHits& hits, int own_label, const cv::Mat& labels,
                 const std::vector<uint8_t>& obstacle, const GripOptions& opt, std::vector<double>& phi,
                 std::vector<double>& d);

}  // namespace rbx1::vision
