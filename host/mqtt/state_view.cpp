// state_view.cpp - folds bus messages into the retained `state` document.
#include "state_view.hpp"

namespace rbx1::mqtt {

std::string mode_of(const nlohmann::json& s) {
  // The firmware's status (motion.cpp status_json): state "FAULT" with faults such as "ESTOP_COMMAND".
  auto f = s.find("firmware");
  if (f != s.end() && f->is_object() && f->value("state", nlohmann::json()) == "FAULT") {
    if (auto faults = f->find("faults"); faults != f->end() && faults->is_array())
      for (const auto& x : *faults)
        if (x.is_string() && x.get<std::string>().rfind("ESTOP", 0) == 0) return "estop";
    return "fault";
  }
  if (auto j = s.find("job"); j != s.end() && !j->is_null()) return "busy";
  if (auto r = s.find("ready"); r != s.end() && r->is_boolean() && r->get<bool>()) return "ready";
  return "not_ready";
}

void StateView::on_status(const nlohmann::json& body) {
  status_ = body;
  for (const char* k : {"topic", "seq", "ts", "t_ms"}) status_.erase(k);
}

void StateView::on_event(const nlohmann::json& body, std::time_t now) {
  nlohmann::json cmd = body.value("cmd", nlohmann::json());
  if (!body.value("final", false)) {
    progress_ = {{"req", body.value("req", nlohmann::json())}, {"cmd", cmd}, {"event", body.value("event", nlohmann::json())}};
    return;
  }
  progress_ = nullptr;
  // A single pick is not in the history (only sorts and clears are): its result is counted here.
  if (cmd == "pick" && body.contains("result")) count_pick(now);
}

nlohmann::json StateView::on_pick_row(const nlohmann::json& body, std::time_t now) {
  if (body.value("outcome", nlohmann::json()) == "picked") count_pick(now);
  nlohmann::json row = body;
  for (const char* k : {"topic", "seq"}) row.erase(k);
  return row;
}

void StateView::count_pick(std::time_t now) {
  tm t{};
  localtime_r(&now, &t);
  if (t.tm_yday != day_) {
    day_ = t.tm_yday;
    picks_today_ = 0;
  }
  ++picks_today_;
}

nlohmann::json StateView::document() const {
  nlohmann::json d = status_;
  d["arm_id"] = arm_id_;
  d["mode"] = mode_of(status_);
  d["progress"] = progress_;
  d["picks_today"] = picks_today_;
  return d;
}

nlohmann::json StateView::take() {
  published_ = document();
  return published_;
}

}  // namespace rbx1::mqtt
