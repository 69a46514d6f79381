// bus.hpp - the daemon's status and event bus: every job event, status change and scan result published once,
// in-process, to any number of subscribers (the socket's subscribe, the console, MQTT, DDS), each with a bounded
// queue that drops its oldest line and counts it, so a subscriber that never reads stalls nothing.
#pragma once
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace rbx1::vision {
struct Scan;
}

namespace rbx1::daemon {

// What a subscriber can ask for. Each message carries its topic in "topic" ("status", "events", "scans", "picks":
// each row of the history's picks table as it is written, the same fields as `rbx1 history --json`).
enum class Topic : unsigned { Status = 1, Events = 2, Scans = 4, Picks = 8 };
inline constexpr unsigned kAllTopics =
    unsigned(Topic::Status) | unsigned(Topic::Events) | unsigned(Topic::Scans) | unsigned(Topic::Picks);
const char* topic_name(Topic t);
// "status" -> Topic::Status; false for an unknown name.
bool topic_from_name(const std::string& name, Topic& out);

// One published message: its topic, a bus-wide sequence number and the JSON object (which has "topic" and "seq").
// A scan also comes as the struct it was written from, for subscribers that want its numbers (ROS 2).
struct BusMessage {
  Topic topic;
  uint64_t seq;
  std::shared_ptr<const nlohmann::json> body;
  std::shared_ptr<const vision::Scan> scan;  // Topic::Scans only
};

class Bus;

// A subscriber's queue: filled by publish() (never blocking it), drained by its reader.
class Subscription {
 public:
  // The next message within timeout_ms; false on timeout or once closed.
  bool next(BusMessage& out, int timeout_ms);
  // Messages dropped because the queue was full when a newer one came (oldest first).
  uint64_t missed() const;
  // Ends the subscription: the reader's next() returns false, the bus forgets it.
  void close();
  bool closed() const;
  unsigned topics() const { return topics_; }

 private:
  friend class Bus;
  Subscription(unsigned topics, size_t capacity) : topics_(topics), capacity_(capacity) {}
  void push(const BusMessage& m);  // publisher side: drop-oldest
  unsigned topics_;
  size_t capacity_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<BusMessage> queue_;
  uint64_t missed_ = 0;
  bool closed_ = false;
};

class Bus {
 public:
  static constexpr size_t kDefaultCapacity = 256;
  // topics: a mask of Topic bits.
  std::shared_ptr<Subscription> subscribe(unsigned topics, size_t capacity = kDefaultCapacity);
  // Adds "topic" and "seq" to body and hands it to every subscriber of the topic. Never blocks on a subscriber.
  uint64_t publish(Topic topic, nlohmann::json body, std::shared_ptr<const vision::Scan> scan = nullptr);
  // The last status published (null before the first): a new subscriber's first status line.
  nlohmann::json last_status() const;
  size_t subscribers() const;

 private:
  mutable std::mutex mu_;
  std::vector<std::weak_ptr<Subscription>> subs_;
  uint64_t seq_ = 0;
  nlohmann::json last_status_;
};

}  // namespace rbx1::daemon
