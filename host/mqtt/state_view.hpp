// state_view.hpp - the `state` topic's document, folded from the bus: the last status, the running job's progress,
// the picks finished today; it knows whether it changed since it was last published.
#pragma once
#include <ctime>
#include <string>

#include <nlohmann/json.hpp>

namespace rbx1::mqtt {

class StateView {
 public:
  explicit StateView(std::string arm_id) : arm_id_(std::move(arm_id)) {}
  // A status message from the bus (the `rbx1 status` fields).
  void on_status(const nlohmann::json& body);
  // An events message from the bus. Returns the `pick` topic's message when it ended a pick, null otherwise.
  nlohmann::json on_event(const nlohmann::json& body, std::time_t now);
  // The document: status fields, "arm_id", "mode" (ready, busy, estop, fault, not_ready), "progress", "picks_today".
  nlohmann::json document() const;
  bool changed() const { return document() != published_; }
  // The document, remembered as published.
  nlohmann::json take();

 private:
  std::string arm_id_;
  nlohmann::json status_ = nlohmann::json::object();
  nlohmann::json progress_;  // {"req", "cmd", "event"} of the running job, null when none
  int picks_today_ = 0;
  int day_ = -1;             // local day of year of picks_today_
  nlohmann::json published_;
};

// "fault", "estop", "busy", "ready" or "not_ready" from a status document (what Home Assistant shows).
std::string mode_of(const nlohmann::json& status);

}  // namespace rbx1::mqtt
