// sort_choice.cpp - the sort's choice of the next object: skip reasons from the detection, the ranking.
#include "sort_choice.hpp"

#include <algorithm>
#include <cmath>

namespace rbx1::daemon {

namespace {
constexpr double kSameObjectCm = 1.0;  // as pick_check.cpp's still_there
}

std::string class_of(const nlohmann::json& object) {
  const auto& label = object.value("label", nlohmann::json(nullptr));
  return label.is_string() ? label.get<std::string>() : kUnknownClass;
}

bool same_object(const nlohmann::json& o, const std::string& cls, const nlohmann::json& c) {
  const auto& oc = o.value("centroid_cm", nlohmann::json(nullptr));
  if (class_of(o) != cls || !oc.is_array() || !c.is_array() || oc.size() != 2 || c.size() != 2) return false;
  return std::hypot(oc[0].get<double>() - c[0].get<double>(), oc[1].get<double>() - c[1].get<double>()) <= kSameObjectCm;
}

Sorting sort_objects(const nlohmann::json& detections, const Recipe& recipe, const std::vector<SeenObject>& given_up) {
  Sorting s;
  const auto& objects = detections["objects"];
  for (size_t i = 0; i < objects.size(); ++i) {
    const auto& o = objects[i];
    std::string cls = class_of(o);
    auto place = place_for(recipe, o.value("label", nlohmann::json(nullptr)));
    if (!place) {
      // An identified class the recipe does not map stays on the table by design; an unidentified one is a skip.
      if (cls == kUnknownClass) s.skips.push_back({i, cls, "unknown_class", "no library entry matches it"});
      else ++s.left[cls];
      continue;
    }
    bool gave_up = std::any_of(given_up.begin(), given_up.end(),
                               [&](const SeenObject& g) { return same_object(o, g.cls, g.centroid_cm); });
    if (gave_up) {
      s.skips.push_back({i, cls, "gave_up", "its pick failed every attempt"});
      continue;
    }
    const auto& grip = o.value("grip", nlohmann::json::object());
    bool touching = o.value("touching", false);
    if (!grip.value("feasible", false)) {
      std::string why = grip.value("reason", nlohmann::json(nullptr)).is_string() ? grip["reason"].get<std::string>() : "";
      if (touching && why == "finger_collision")
        s.skips.push_back({i, cls, "touching", "a neighbour leaves no room for a finger"});
      else
        s.skips.push_back({i, cls, "infeasible_grip", why.empty() ? "no feasible grip" : why});
      continue;
    }
    s.candidates.push_back({i, cls, *place, touching, 0});
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
