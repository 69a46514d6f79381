// scan_json.hpp - the one writer of a Scan as JSON (`rbx1 detect --json`, README.md "JSON"), for every edge that
// speaks JSON: the CLI, the daemon's replies and events, its bus (socket, console, MQTT). Inside the daemon scans
// travel as structs. nlohmann's to_json hooks: `nlohmann::json j = scan;` and {"grip", object.grip} just work.
#pragma once
#include <optional>

#include <nlohmann/json.hpp>

#include "types.hpp"

namespace rbx1::vision {

void to_json(nlohmann::json& j, const Scan& scan);
void to_json(nlohmann::json& j, const ScanObject& object);
void to_json(nlohmann::json& j, const Grip& grip);  // an object's "grip": contacts, opening, angle, feasible, reason

// A point as the document writes it, [x, y], or null (centroid_cm when uncalibrated).
nlohmann::json point_json(const std::optional<cv::Point2d>& p);
// A number or null.
nlohmann::json number_json(const std::optional<double>& v);

}  // namespace rbx1::vision
