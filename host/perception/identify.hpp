// identify.hpp - object identification (paper step IV): the profile at the reference orientation against the library.
#pragma once
#include <optional>
#include <vector>

#include "grip.hpp"
#include "library.hpp"
#include "types.hpp"

namespace rbx1::vision {

struct MatchOptions {
  double threshold = 0.5;     // score below this: unknown
  double shape_sigma = 0.035; // RMS profile difference (in sqrt(area) units) that costs a factor exp(-1/2)
  double size_sigma = 0.15;   // |log size ratio| that costs exp(-1/2); 0: size is ignored
  // Seen from above, an object of some height looks larger than its footprint (its top is nearer the camera, its
  // sides show away from the optical axis), never smaller: growth up to this fraction of the taught linear size
  // costs nothing. In tools/world's frames (camera 490 mm up) objects 4-12 mm tall looked 2-14 % larger.
  double size_grow = 0.15;
  int angle_slack_bins = 1;   // each value is compared with the other profile's range over +-this many bins
};

// Outermost contour crossing per direction, measured from the principal axis (the reference orientation),
// divided by sqrt(area): rays handle shapes that are not star-shaped around their centroid.
std::vector<double> identity_profile(const Geometry& g, const Pose& p, const RayHits& hits, int lines);

struct Match {
  int entry = -1;      // best library entry, -1 if the library is empty
  double score = 0;    // in [0, 1]
};
// Tries both ends of the axis (180-degree ambiguity), every rotation for near-isotropic objects, and the
// mirror image for entries that allow it. The shape term tolerates a misalignment of angle_slack_bins: where a
// ray grazes a corner or an edge (an L's inner corner next to its centroid) r jumps within a bin, and a fraction
// of a degree of axis or a tenth of a millimetre of centroid moves the jump into the neighbouring bin.
// area_cm2 is used for the size term when both sides have it.
Match identify(const Library& lib, const std::vector<double>& profile, double area_px, std::optional<double> area_cm2,
               double elongation, const MatchOptions& opt);

}  // namespace rbx1::vision
