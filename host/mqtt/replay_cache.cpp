// replay_cache.cpp - ids seen in the last ttl with their first reply; the oldest go first when the table is full.
#include "replay_cache.hpp"

namespace rbx1::mqtt {

void ReplayCache::expire(double now_s) {
  for (size_t n = order_.size(); n > 0 && (order_.front().first < now_s - ttl_s_ || order_.size() > max_entries_); --n) {
    auto [seen, key] = std::move(order_.front());
    order_.pop_front();
    auto it = entries_.find(key);
    if (it == entries_.end()) continue;
    if (it->second.done) {
      entries_.erase(it);
    } else {
      // Still running: its waiters are owed a reply, and a repeat must not run it. Its time starts again.
      it->second.seen_s = now_s;
      order_.emplace_back(now_s, std::move(key));
    }
  }
}

ReplayCache::Seen ReplayCache::check(const std::string& key, double now_s, std::string& reply, Waiter waiter) {
  std::lock_guard lock(mu_);
  expire(now_s);
  auto it = entries_.find(key);
  if (it == entries_.end()) {
    Entry e;
    e.seen_s = now_s;
    entries_.emplace(key, std::move(e));
    order_.emplace_back(now_s, key);
    return Seen::New;
  }
  if (it->second.done) {
    reply = it->second.reply;
    return Seen::Done;
  }
  it->second.waiters.push_back(std::move(waiter));
  return Seen::Pending;
}

void ReplayCache::finish(const std::string& key, const std::string& final_line) {
  std::vector<Waiter> waiters;
  {
    std::lock_guard lock(mu_);
    auto it = entries_.find(key);
    if (it == entries_.end()) return;
    it->second.done = true;
    it->second.reply = final_line;
    waiters.swap(it->second.waiters);
  }
  for (auto& w : waiters) w(final_line);
}

size_t ReplayCache::size() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

}  // namespace rbx1::mqtt
