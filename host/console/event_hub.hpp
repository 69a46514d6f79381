// event_hub.hpp - the console's event log: every line of the requests made through it, numbered, kept in a ring,
// handed to every server-sent-events stream.
#pragma once
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace rbx1::console {

struct HubEvent {
  uint64_t seq;      // 1, 2, ... in publication order
  std::string data;  // one JSON object (no newline)
};

class EventHub {
 public:
  explicit EventHub(size_t keep = 300) : keep_(keep) {}
  // Adds "seq" to the object and stores it; returns its seq.
  uint64_t publish(nlohmann::json event);
  // The kept events after seq `after` (all kept ones for 0), waiting up to `timeout` when there are none.
  // Empty after close() or on timeout.
  std::vector<HubEvent> wait(uint64_t after, std::chrono::milliseconds timeout);
  // The arm's latest status (the bus's): not an event of the log, only the newest is kept.
  void set_status(const nlohmann::json& status);
  // As wait(), and also returns when the status changed since status_seen (0: none seen yet): then status holds
  // it and status_seen its number; else status is empty.
  std::vector<HubEvent> wait(uint64_t after, uint64_t& status_seen, std::string& status, std::chrono::milliseconds timeout);
  void close();
  bool closed() const;
  uint64_t last_seq() const;

 private:
  size_t keep_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<HubEvent> ring_;
  uint64_t seq_ = 0;
  std::string status_;
  uint64_t status_seq_ = 0;
  bool closed_ = false;
};

}  // namespace rbx1::console
