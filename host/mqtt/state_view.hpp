// state_view.hpp - the `state` topic's document, folded from the bus: the last status, the running job's progress,
// the objects picked today; it knows whether it changed since it was last published.
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
  // An events message from the bus (the running job's progress; a single pick's result counts in picks_today).
  void on_event(const nlohmann::json& body, std::time_t now);
  // A picks message from the bus (a sort's or clear's history row; "picked" counts). Returns the `pick` topic's
  // message: the row itself, without the bus's "topic" and "seq".
  nlohmann::json on_pick_row(const nlohmann::json& body, std::time_t now);
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
  void count_pick(std::time_t now);  // picks_today + 1, from 0 on a new local day
};

// "fault", "estop", "busy", "ready" or "not_ready" from a status document (what Home Assistant shows).
std::string mode_of(const nlohmann::json& status);

}  // namespace rbx1::mqtt
