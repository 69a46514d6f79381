// pick_check.cpp - the daemon checks its own work: after a pick, a fresh scan must no longer show the object
// where it was picked from; else a pick_failed event and, as configured, a new pick from that fresh detection.
// A check frame that finds nothing where the scan before found several objects proves nothing (the light
// dropped, the lens was covered: issue 27): it is taken once more, and a second blind frame is a
// pick_unverified error, never a verified pick.
#include <cmath>

#include "machine.hpp"
#include "pick_plan.hpp"

namespace rbx1::daemon {

namespace {
// A detection of the same label this close to where the object was picked from is the object itself: objects
// are laid out apart by more than a finger (the grip check keeps a finger's width to every neighbour).
constexpr double kStillThereCm = 1.0;

const nlohmann::json* still_there(const nlohmann::json& detections, const std::string& name, const nlohmann::json& c) {
  const nlohmann::json* best = nullptr;
  double best_d = kStillThereCm;
  for (const auto& o : detections["objects"]) {
    if (!o["label"].is_string() || o["label"].get<std::string>() != name || !o["centroid_cm"].is_array()) continue;
    double d = std::hypot(o["centroid_cm"][0].get<double>() - c[0].get<double>(),
                          o["centroid_cm"][1].get<double>() - c[1].get<double>());
    if (d <= best_d) {
      best_d = d;
      best = &o;
    }
  }
  return best;
}

// Blind: no object at all where the scan before found two or more (one was picked, the others should remain).
bool blind(const nlohmann::json& detections, size_t before) { return before >= 2 && detections["objects"].empty(); }
}  // namespace

bool Machine::check_pick(Reply& reply, const std::string& name, const std::string& place, nlohmann::json picked,
                         size_t scanned, nlohmann::json& result) {
  for (int attempt = 1;; ++attempt) {
    if (!move_to(reply, "check_scan", config_.arm.scan)) return false;
    nlohmann::json detections;
    std::string report;
    for (int frame = 1;; ++frame) {
      if (!capture_and_detect(reply, detections, report)) return false;
      if (!blind(detections, scanned)) break;
      reply.event("check_blind", {{"name", name}, {"attempt", attempt}, {"frame", frame}, {"before", scanned}});
      if (frame == 2) {
        if (!move_to(reply, "home", config_.arm.home)) return false;
        reply.error("pick_unverified", "the check after picking \"" + name + "\" found no object in two frames where " +
                                           "the scan before found " + std::to_string(scanned) +
                                           ": the camera sees nothing (light changed, lens covered?); the pick is not verified");
        return false;
      }
    }
    scanned = detections["objects"].size();
    const nlohmann::json* left = still_there(detections, name, picked["centroid_cm"]);
    if (!left) {
      reply.event("pick_verified", {{"name", name}, {"attempt", attempt}, {"centroid_cm", picked["centroid_cm"]}});
      if (!move_to(reply, "home", config_.arm.home)) return false;
      result["verified"] = true;
      result["attempts"] = attempt;
      return true;
    }
    bool retry = attempt <= config_.daemon.pick_retries;
    reply.event("pick_failed", {{"name", name}, {"attempt", attempt}, {"reason", "still_there"},
                                {"centroid_cm", (*left)["centroid_cm"]}, {"retry", retry}});
    if (!retry) {
      if (!move_to(reply, "home", config_.arm.home)) return false;
      reply.error("pick_failed", "\"" + name + "\" is still where it was picked from after " +
                                     std::to_string(attempt) + (attempt == 1 ? " attempt" : " attempts"));
      return false;
    }
    // Again, from the fresh detection (the arm is at the scan pose it was taken from).
    picked = *left;
    std::vector<MotionStep> steps;
    nlohmann::json plan_info;
    std::string error;
    if (!plan_pick(detections, picked, place, steps, plan_info, error)) {
      if (!move_to(reply, "home", config_.arm.home)) return false;
      reply.error("pick_failed", "cannot pick \"" + name + "\" again: " + error);
      return false;
    }
    plan_info["steps"] = steps.size();
    plan_info["attempt"] = attempt + 1;
    reply.event("planned", plan_info);
    MotionResult motion;
    if (!run_steps(reply, steps, motion)) return false;
  }
}

}  // namespace rbx1::daemon
