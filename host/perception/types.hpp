// types.hpp - the data one object carries through the pipeline: its layer, geometry, pose, identity and grip.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::vision {

enum class Polarity { Auto, Dark, Light };

// The paper's per-object layer, cut to the object's bounding box (ROI) instead of a full-frame array.
struct Layer {
  int label = 0;     // component id in the frame's label image
  cv::Rect roi;      // in frame pixels
  cv::Mat soft;      // CV_32F roi: 1 inside, 0 outside, the covered fraction on the edge band
  cv::Mat inside;    // CV_8U roi: 255 where soft >= 0.5 (the object's binary layer)
  std::vector<cv::Point> outer;  // outer boundary pixels of inside (largest piece), roi coordinates
  std::vector<std::pair<double, std::vector<cv::Point>>> pieces;  // isolation only: pieces by area
  bool touching = false;  // cut from a region it shared with a touching neighbour
  int sign = -1;          // -1: darker than the background, +1: lighter, 0: both (a two-colour object)
  double level = 0;       // median contrast of the object (grey levels)
};

// An edge point (paper Eq. 1-2) moved to its sub-pixel position, in frame pixels; w = contour length it stands for.
struct EdgePoint {
  double x = 0, y = 0, w = 1;
};

struct Geometry {
  cv::Point2d centroid;               // area centroid of the soft layer
  double area_px = 0;                 // covered area (sum of the soft layer)
  // The area at the half level, what identification compares (measure_geometry): the layer's anti-aliased edge
  // counted at its fraction, a shadow or fringe fainter than a third of the object's contrast not at all.
  double half_area_px = 0;
  double mu20 = 0, mu02 = 0, mu11 = 0;  // central second moments of the area, per unit area
  int edge_pixels = 0;                // pixels of the layer with |G| > t (paper Eq. 1-2): the edge image
  std::vector<EdgePoint> contour;     // outer contour: its edge pixels moved to sub-pixel positions, ordered
  std::vector<double> theta, r;       // r-theta profile (Eq. 3-4): edge points sorted by angle, theta in [0, 2pi)
  // Per contour point (its order), about the centroid: atan2 in [-pi, pi] and the distance, set by
  // measure_geometry so the grip's ray casting reuses them; empty (or stale in size) means computed afresh.
  std::vector<double> psi, rho;
};

struct Pose {
  double orientation_deg = 0;   // principal axis, (-90, 90], +x towards +y
  std::optional<double> slope, intercept;  // axis line y = slope x + intercept (none for a vertical axis)
  double elongation = 1;        // sqrt of the eigenvalue ratio (= aspect ratio of a rectangle or ellipse)
  bool elongated = false;
};

// Why a grip is not feasible (shared/DESIGN.md: grip.reason).
enum class GripReason { None, TooWide, TooNarrow, NoContact, FingerCollision };
const char* grip_reason_name(GripReason r);  // "too_wide", ...; nullptr for None

struct Grip {
  cv::Point2d p1, p2;           // contact points; p1 -> p2 is the closing direction
  double opening_px = 0;
  double angle_deg = 0;         // direction p1 -> p2, (-90, 90]
  bool clear = true;            // fingers do not land on another object
  bool feasible = false;        // both contacts real, opening within the gripper, fingers clear
  GripReason reason = GripReason::NoContact;
  std::optional<double> opening_cm;
};

// Identification's verdict on an object (identify.hpp judge).
enum class Verdict { Known, NoLibrary, BelowThreshold, Ambiguous };

struct Identity {
  std::optional<std::string> label;  // the taught name, when the verdict is Known
  std::optional<double> score;       // its score (null with the label)
  // The match behind it (with a library), also for an unknown object: the best entry, its threshold, the
  // runner-up (second best entry) and why the label is null.
  std::optional<std::string> best, runner_up;
  std::optional<double> best_score, threshold, runner_up_score;
  Verdict verdict = Verdict::NoLibrary;
};

struct DetectedObject {
  int index = 0;  // detection order, 1-based
  Layer layer;
  Geometry geometry;
  Pose pose;
  Grip grip;
  Identity identity;
  std::vector<double> chord_phi, chord_d;  // D(phi) for phi in [0, pi): the gripper opening per closing direction
  std::optional<cv::Point2d> centroid_cm;
  bool touching = false;  // split from a neighbour it touched (its grip checks that neighbour's clearance)
};

// What a scan reports: one object of `rbx1 detect --json`'s "objects" (README.md "JSON"), the pipeline's figures
// rounded as the document prints them (Vision::scan), so that what the daemon plans from is exactly what its
// clients are shown. scan_json.hpp writes it; a new field is one member here, one line there.
struct ScanObject {
  int index = 0;                           // detection order, 1-based
  Identity identity;                       // score only with a label (below the threshold: unknown, no score)
  cv::Point2d centroid_px;
  std::optional<cv::Point2d> centroid_cm;  // calibrated only
  long area_px = 0;
  int edge_points = 0;
  Pose pose;                               // orientation, axis line, elongation
  Grip grip;                               // opening_cm calibrated only; reason: why not feasible
  bool touching = false;
};

// One frame's scan: the whole `rbx1 detect --json` document.
struct Scan {
  cv::Size image;
  std::optional<double> px_per_cm;         // at the frame's centre; calibrated only
  std::vector<ScanObject> objects;
  std::vector<std::string> warnings;       // why the objects may be wrong or missing (written only when some)
};

}  // namespace rbx1::vision
