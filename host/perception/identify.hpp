// identify.hpp - object identification (paper step IV): the profile at the reference orientation against the library.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "grip.hpp"
#include "library.hpp"
#include "pose.hpp"
#include "types.hpp"

namespace rbx1::vision {

struct MatchOptions {
  double threshold = 0.5;     // score below this: unknown (every entry; a learnt LibraryEntry::threshold raises it)
  // Two taught entries that both accept an object (each at or above its own threshold): the better one is
  // taken only this far ahead, else the object is unknown (ambiguous between look-alikes).
  double min_margin = 0.05;
  double shape_sigma = 0.035; // RMS profile difference (in sqrt(area) units) that costs a factor exp(-1/2)
  double size_sigma = 0.15;   // |log size ratio| that costs exp(-1/2); 0: size is ignored
  // Seen from above, an object of some height looks larger than its footprint (its top is nearer the camera, its
  // sides show away from the optical axis), never smaller: growth up to this fraction of the taught linear size
  // costs nothing. In tools/world's frames (camera 490 mm up) objects 4-12 mm tall looked 2-14 % larger.
  double size_grow = 0.15;
  int angle_slack_bins = 1;   // each value is compared with the other profile's range over +-this many bins
};

// Outermost contour crossing per direction, measured from the principal axis (the reference orientation),
// divided by sqrt(half_area_px): rays handle shapes that are not star-shaped around their centroid.
std::vector<double> identity_profile(const Geometry& g, const Pose& p, const RayHits& hits, int lines);

// A seen object's size, by both of an entry's possible area kinds (LibraryEntry::area_kind).
struct SeenArea {
  double half_px = 0, layer_px = 0;
  double px_per_cm = 0;  // the scale at the object; 0 uncalibrated
  static SeenArea of(const Geometry& g, double px_per_cm) { return {g.half_area_px, g.area_px, px_per_cm}; }
};

struct Match {
  int entry = -1;      // best library entry, -1 if the library is empty
  double score = 0;    // in [0, 1]
  int runner_up = -1;  // second best entry, -1 with fewer than two entries
  double runner_up_score = 0;
};
// Tries both ends of the axis (180-degree ambiguity), every rotation for near-isotropic objects, and the
// mirror image for entries that allow it. The shape term tolerates a misalignment of angle_slack_bins: where a
// ray grazes a corner or an edge (an L's inner corner next to its centroid) r jumps within a bin, and a fraction
// of a degree of axis or a tenth of a millimetre of centroid moves the jump into the neighbouring bin.
// The size term compares cm² when both sides are calibrated, else px; each entry by its own area kind (an entry
// of the soft layer's area gets the profile rescaled to that area: it matches exactly as it did).
Match identify(const Library& lib, const std::vector<double>& profile, const SeenArea& area, double elongation,
               const MatchOptions& opt);

// Whether a match names its object (issue 27: an untaught look-alike stays unknown). The best entry must score
// at least its own threshold (the learnt one, never below opt.threshold; opt.threshold for entries without one),
// and when the runner-up also reaches its own threshold, the best must lead it by opt.min_margin.
const char* verdict_name(Verdict v);  // "known", "no_library", "below_threshold", "ambiguous"
double entry_threshold(const LibraryEntry& e, const MatchOptions& opt);
Verdict judge(const Library& lib, const Match& m, const MatchOptions& opt);
// The object's identity from its match: label and score when judged known; best, runner-up and verdict always.
Identity identity_of(const Library& lib, const Match& m, const MatchOptions& opt);

// The taught object's own views: its sub-pixel contour turned to angles all round, its edge moved in or out
// (blur and threshold), scaled (camera height) and jittered (noise), each measured again (centroid, pose,
// rays, profile) and matched against the entry. The threshold is what those views score, widened by
// kThresholdSpread in the score's exponent (z = sqrt(-2 ln score)) and never below opt.threshold:
// a shape whose views score 0.98 accepts from about 0.92, one whose own views vary (a thin L) accepts lower.
inline constexpr int kSelfViews = 32;
inline constexpr double kViewOffsetPx = 0.3;   // edge moved in or out by up to this (blur, threshold level)
inline constexpr double kViewNoisePx = 0.1;    // per contour point (sensor noise on the sub-pixel edge)
inline constexpr double kViewScale = 0.02;     // linear size within 1 +- this (camera height, calibration)
inline constexpr double kThresholdSpread = 2.0;  // z of the threshold = this times z of the worst own view
inline constexpr double kThresholdMinZ = 0.4;    // at least this z (score 0.92): views are never perfect
struct SelfViews {
  double worst = 1, median = 1;  // scores of the object's own views
  double threshold = 0.5;        // the entry's learnt threshold
};
SelfViews learn_threshold(const Geometry& g, const LibraryEntry& entry, const MatchOptions& opt,
                          const PoseOptions& pose, int lines);

// An entry already in the library that a new entry's object would be taken for or confused with (issue 27: a
// second name taught for the same object made twins silently). The new entry's own profile, matched against
// each other entry alone, scores at least that entry's threshold or the new one's: one of them accepts the
// other's object. ambiguous: the score is within opt.min_margin of a perfect view of its own (1), so an object
// of either shape will be ambiguous and a pick by either name answers it unknown.
struct Lookalike {
  std::string name;
  double score = 0, threshold = 0;  // the match, and the threshold it reached (the larger one reached)
  bool ambiguous = false;
};
std::vector<Lookalike> lookalikes(const Library& lib, const LibraryEntry& entry, const MatchOptions& opt);
// One line for the user: which entry, the score, and what follows for picks by either name.
std::string lookalike_warning(const std::string& taught, const Lookalike& l);

}  // namespace rbx1::vision
