// scan_json.cpp - Scan -> the `rbx1 detect --json` document. The figures are already rounded (Vision::scan):
// this only names them.
#include "scan_json.hpp"

#include <cmath>

#include "identify.hpp"

namespace rbx1::vision {

using nlohmann::json;

json point_json(const std::optional<cv::Point2d>& p) { return p ? json{p->x, p->y} : json(nullptr); }

json number_json(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

namespace {
// Why the grip is not feasible ("too_wide", ...); null when it is.
json reason_json(const Grip& g) {
  const char* why = g.feasible ? nullptr : grip_reason_name(g.reason);
  return why ? json(why) : json(nullptr);
}

// The match behind label/match_score: null without a library.
json identification_json(const Identity& id) {
  if (id.verdict == Verdict::NoLibrary) return nullptr;
  json margin = nullptr;
  if (id.best_score && id.runner_up_score) margin = std::round((*id.best_score - *id.runner_up_score) * 1e4) / 1e4;
  auto name = [](const std::optional<std::string>& v) { return v ? json(*v) : json(nullptr); };
  return {{"verdict", verdict_name(id.verdict)}, {"best", name(id.best)}, {"best_score", number_json(id.best_score)},
          {"threshold", number_json(id.threshold)}, {"runner_up", name(id.runner_up)},
          {"runner_up_score", number_json(id.runner_up_score)}, {"margin", margin}};
}
}  // namespace

void to_json(json& j, const Grip& g) {
  j = {{"p1_px", point_json(g.p1)},
       {"p2_px", point_json(g.p2)},
       {"opening_px", g.opening_px},
       {"opening_cm", number_json(g.opening_cm)},
       {"angle_deg", g.angle_deg},
       {"feasible", g.feasible},
       {"reason", reason_json(g)}};
}

void to_json(json& j, const ScanObject& o) {
  j = {{"index", o.index},
       {"label", o.identity.label ? json(*o.identity.label) : json(nullptr)},
       {"match_score", number_json(o.identity.score)},
       {"centroid_px", point_json(o.centroid_px)},
       {"centroid_cm", point_json(o.centroid_cm)},
       {"area_px", o.area_px},
       {"edge_points", o.edge_points},
       {"orientation_deg", o.pose.orientation_deg},
       {"axis_line", {{"slope", number_json(o.pose.slope)}, {"intercept", number_json(o.pose.intercept)}}},
       {"elongation", o.pose.elongation},
       {"elongated", o.pose.elongated},
       {"grip", o.grip},
       {"touching", o.touching},
       {"identification", identification_json(o.identity)}};
}

void to_json(json& j, const Scan& s) {
  j = {{"image", {{"width", s.image.width}, {"height", s.image.height}}},
       {"px_per_cm", number_json(s.px_per_cm)},
       {"objects", s.objects}};
  if (!s.warnings.empty()) j["warnings"] = s.warnings;  // only when the method could not decide
}

}  // namespace rbx1::vision
