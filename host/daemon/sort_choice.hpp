// sort_choice.hpp - which object a sort or clear picks next: the scan's objects under a recipe, those that cannot
// be picked safely skipped with a reason, the rest ranked (disturbs no neighbour first, then shortest travel).
#pragma once
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "recipes.hpp"
#include "types.hpp"

namespace rbx1::daemon {

// An object known by its class and where it lay (centroid_cm): objects do not move unless picked.
struct SeenObject {
  std::string cls;
  std::optional<cv::Point2d> centroid_cm;
};

struct Candidate {
  size_t index = 0;       // into the scan's objects
  std::string cls;        // label or "unknown"
  std::string place;
  bool disturbs = false;  // split from a neighbour it touches: lifting it may drag the neighbour along
  double travel_ms = 0;   // the pick's planned motion from the scan pose (set by the caller after planning)
};

struct Skip {
  size_t index = 0;
  std::string cls;
  std::string reason;  // infeasible_grip, touching, unknown_class, unreachable, gave_up, not_confirmed
  std::string detail;  // the grip's own reason, the planner's error, the attempts, what it was seen as
};

// An object the job will not pick again, and why (gave_up: its attempts failed; not_confirmed: seen from
// straight above it was not its class).
struct SetAside {
  SeenObject object;
  std::string reason, detail;
};

struct Sorting {
  std::vector<Candidate> candidates;  // unranked
  std::vector<Skip> skips;
  std::map<std::string, int> left;    // classes the recipe does not map, left on the table
};

// A scanned object of cls (or unlabelled, best matching cls) within 1 cm of centroid_cm: the same object (objects
// lie apart by more than a finger).
bool same_object(const vision::ScanObject& object, const std::string& cls, const std::optional<cv::Point2d>& centroid_cm);
// Of the scan's objects of cls, the nearest to centroid_cm within that distance; null when none.
const vision::ScanObject* find_same(const vision::Scan& scan, const std::string& cls,
                                    const std::optional<cv::Point2d>& centroid_cm);
std::string class_of(const vision::ScanObject& object);  // its label, or "unknown"

// The objects of the scan under recipe; those matching an object set aside are skipped with its reason.
Sorting sort_objects(const vision::Scan& scan, const Recipe& recipe, const std::vector<SetAside>& set_aside);
// Candidates that disturb no neighbour first, then the shortest planned travel; ties by detection order.
void rank(std::vector<Candidate>& candidates);

}  // namespace rbx1::daemon
