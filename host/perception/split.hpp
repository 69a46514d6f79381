// split.hpp - touching objects: one region with two or more bodies joined by a neck is cut apart (distance
// transform, persistence of its maxima, marker watershed).
#pragma once
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::vision {

struct SplitOptions {
  double min_persistence_px = 3;   // a body's peak must stand this far above the neck that joins it...
  double min_persistence_rel = 0.3;  // ...and this fraction of its own peak, at least 0.5 (split.cpp: the neck
                                     // under half the body's width)
  double max_solidity = 0.93;      // regions more convex than this are one object (no neck to cut)
  int min_area_px = 40;            // each body at least this big
  double min_cut_depth_px = 2.5;   // both ends of a cut at least this deep in a concavity of the outline
                                   // (their distance to the region's convex hull)
  double min_body_ratio = 0.25;    // the smaller of two bodies at least this fraction of the larger's area: a
                                   // leaf on its stem, a ball on a prong, a handle's grip is part of its body
  double neck_opening = 0.5;       // the region widens to (1 + this) times the neck within 4 neck half-widths
                                   // + 8 px of the cut (both sides' distances added): two objects meet at a
                                   // pinch; a stem, a handle's shaft, a dumbbell's bar stays narrow for its length
};

// mask: CV_8U region (255 inside). Returns the number of bodies found (1: not split); when > 1, `parts`
// (CV_32S, mask's size) holds 1..n for the bodies and 0 outside. Each cut runs along the neck's watershed and
// has both ends in concavities of the outline, the smaller body is at least min_body_ratio of the larger and the
// region widens from the neck on both sides within a short distance (else its two bodies are one).
int split_touching(const cv::Mat& mask, const SplitOptions& opt, cv::Mat& parts);

// Touching objects of clearly different contrast (levels, the medians over their bodies, at least 4 noise sigma
// and a fifth of the stronger apart: a dark sweet in front of a red one) meet where the contrast crosses the
// level half-way between them, not where the outline is narrowest. contrast: CV_8U, parts' size; `parts`
// (1..n from split_touching) is re-cut in place: each body keeps the largest connected part of its pixels on its
// own side of every such neighbour's half-way level (leaving out the band within 2 px of the outline: edges over
// the table, at every level), and the rest joins its neighbours by seeded region growing (closest to a
// neighbour's level first, the band last and nearest first). Bodies of like levels keep their cut.
void cut_between_levels(const cv::Mat& contrast, double noise_sigma, int bodies, cv::Mat& parts);

}  // namespace rbx1::vision
