// sort_choice.cpp - the sort's choice of the next object: skip reasons from the scan, the ranking.
#include "sort_choice.hpp"

#include <algorithm>
#include <cmath>

namespace rbx1::daemon {

namespace {
// Objects are laid out apart by more than a finger (the grip check keeps a finger's width to every neighbour).
constexpr double kSameObjectCm = 1.0;

// How far o lies from c (cm); none when either is unknown (uncalibrated).
std::optional<double> distance_cm(const vision::ScanObject& o, const std::optional<cv::Point2d>& c) {
  if (!o.centroid_cm || !c) return std::nullopt;
  return std::hypot(o.centroid_cm->x - c->x, o.centroid_cm->y - c->y);
}
}  // namespace

std::string class_of(const vision::ScanObject& o) { return o.identity.label.value_or(kUnknownClass); }

bool same_object(const vision::ScanObject& o, const std::string& cls, const std::optional<cv::Point2d>& c) {
  // An unlabelled object whose best match is cls counts too: near its learnt threshold, a second look may fall
  // just under it, and the object is still there, not gone.
  bool looks_like = class_of(o) == cls || (!o.identity.label && o.identity.best == cls);
  auto d = distance_cm(o, c);
  return looks_like && d && *d <= kSameObjectCm;
}

const vision::ScanObject* find_same(const vision::Scan& scan, const std::string& cls,
                                    const std::optional<cv::Point2d>& c) {
  const vision::ScanObject* best = nullptr;
  for (const auto& o : scan.objects)
    if (same_object(o, cls, c) && (!best || *distance_cm(o, c) <= *distance_cm(*best, c))) best = &o;
  return best;
}

Sorting sort_objects(const vision::Scan& scan, const Recipe& recipe, const std::vector<SetAside>& set_aside) {
  Sorting s;
  for (size_t i = 0; i < scan.objects.size(); ++i) {
    const vision::ScanObject& o = scan.objects[i];
    std::string cls = class_of(o);
    auto place = place_for(recipe, o.identity.label);
    if (!place) {
      // An identified class the recipe does not map stays on the table by design; an unidentified one is a skip.
      if (cls == kUnknownClass) s.skips.push_back({i, cls, "unknown_class", "no library entry matches it"});
      else ++s.left[cls];
      continue;
    }
    auto aside = std::find_if(set_aside.begin(), set_aside.end(), [&](const SetAside& a) {
      return same_object(o, a.object.cls, a.object.centroid_cm);
    });
    if (aside != set_aside.end()) {
      s.skips.push_back({i, cls, aside->reason, aside->detail});
      continue;
    }
    if (!o.grip.feasible) {
      const char* why = vision::grip_reason_name(o.grip.reason);
      if (o.touching && o.grip.reason == vision::GripReason::FingerCollision)
        s.skips.push_back({i, cls, "touching", "a neighbour leaves no room for a finger"});
      else
        s.skips.push_back({i, cls, "infeasible_grip", why ? why : "no feasible grip"});
      continue;
    }
    s.candidates.push_back({i, cls, *place, o.touching, 0});
  }
  return s;
}

void rank(std::vector<Candidate>& c) {
  std::stable_sort(c.begin(), c.end(), [](const Candidate& a, const Candidate& b) {
    if (a.disturbs != b.disturbs) return !a.disturbs;
    return a.travel_ms < b.travel_ms;
  });
}

}  // namespace rbx1::daemon
