// replay_cache.hpp - at most once: a command id seen within the last ttl is answered with its first reply and never
// runs again (a QoS 1 redelivery, a sender's retry after a reconnect).
#pragma once
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

namespace rbx1::mqtt {

class ReplayCache {
 public:
  // Gets the first reply's final line once it is known.
  using Waiter = std::function<void(const std::string& final_line)>;
  enum class Seen { New, Done, Pending };

  explicit ReplayCache(double ttl_s = 600, size_t max_entries = 10000) : ttl_s_(ttl_s), max_entries_(max_entries) {}
  // New: the caller runs the command and later calls finish(key). Done: reply holds the first reply. Pending: the
  // first is still running; waiter gets its reply when it ends.
  Seen check(const std::string& key, double now_s, std::string& reply, Waiter waiter);
  // The first run's final line: kept for repeats, and handed to the waiters (outside the lock).
  void finish(const std::string& key, const std::string& final_line);
  size_t size() const;

 private:
  struct Entry {
    double seen_s = 0;
    bool done = false;
    std::string reply;
    std::vector<Waiter> waiters;
  };
  void expire(double now_s);  // mu_ held

  double ttl_s_;
  size_t max_entries_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, Entry> entries_;
  std::deque<std::pair<double, std::string>> order_;  // (seen, key), oldest first
};

}  // namespace rbx1::mqtt
