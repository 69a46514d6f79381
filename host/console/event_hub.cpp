// event_hub.cpp - a bounded, numbered event ring with blocking readers (the server-sent-events streams).
#include "event_hub.hpp"

namespace rbx1::console {

uint64_t EventHub::publish(nlohmann::json event) {
  std::lock_guard lock(mutex_);
  event["seq"] = ++seq_;
  ring_.push_back({seq_, event.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)});
  while (ring_.size() > keep_) ring_.pop_front();
  cv_.notify_all();
  return seq_;
}

std::vector<HubEvent> EventHub::wait(uint64_t after, std::chrono::milliseconds timeout) {
  uint64_t no_status = UINT64_MAX;
  std::string unused;
  return wait(after, no_status, unused, timeout);
}

void EventHub::set_status(const nlohmann::json& status) {
  std::lock_guard lock(mutex_);
  status_ = status.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  ++status_seq_;
  cv_.notify_all();
}

std::vector<HubEvent> EventHub::wait(uint64_t after, uint64_t& status_seen, std::string& status,
                                     std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, timeout, [&] { return closed_ || seq_ > after || status_seq_ > status_seen; });
  std::vector<HubEvent> out;
  status.clear();
  if (closed_) return out;
  if (status_seq_ > status_seen) {
    status = status_;
    status_seen = status_seq_;
  }
  for (const auto& e : ring_)
    if (e.seq > after) out.push_back(e);
  return out;
}

void EventHub::close() {
  std::lock_guard lock(mutex_);
  closed_ = true;
  cv_.notify_all();
}

bool EventHub::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

uint64_t EventHub::last_seq() const {
  std::lock_guard lock(mutex_);
  return seq_;
}

}  // namespace rbx1::console
