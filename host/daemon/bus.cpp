// bus.cpp - publish to every live subscriber of a topic; a full queue drops its oldest message and counts it.
#include "bus.hpp"

#include <algorithm>
#include <chrono>

namespace rbx1::daemon {

namespace {
constexpr struct {
  Topic topic;
  const char* name;
} kTopics[] = {{Topic::Status, "status"}, {Topic::Events, "events"}, {Topic::Scans, "scans"}, {Topic::Picks, "picks"}};
}  // namespace

const char* topic_name(Topic t) {
  for (const auto& e : kTopics)
    if (e.topic == t) return e.name;
  return "?";
}

bool topic_from_name(const std::string& name, Topic& out) {
  for (const auto& e : kTopics)
    if (name == e.name) {
      out = e.topic;
      return true;
    }
  return false;
}

void Subscription::push(const BusMessage& m) {
  {
    std::lock_guard lock(mu_);
    if (closed_) return;
    if (queue_.size() >= capacity_) {
      queue_.pop_front();
      ++missed_;
    }
    queue_.push_back(m);
  }
  cv_.notify_one();
}

bool Subscription::next(BusMessage& out, int timeout_ms) {
  std::unique_lock lock(mu_);
  if (!cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return closed_ || !queue_.empty(); }))
    return false;
  if (closed_) return false;
  out = std::move(queue_.front());
  queue_.pop_front();
  return true;
}

uint64_t Subscription::missed() const {
  std::lock_guard lock(mu_);
  return missed_;
}

void Subscription::close() {
  {
    std::lock_guard lock(mu_);
    closed_ = true;
    queue_.clear();
  }
  cv_.notify_all();
}

bool Subscription::closed() const {
  std::lock_guard lock(mu_);
  return closed_;
}

std::shared_ptr<Subscription> Bus::subscribe(unsigned topics, size_t capacity) {
  std::shared_ptr<Subscription> s(new Subscription(topics, std::max<size_t>(capacity, 1)));
  std::lock_guard lock(mu_);
  subs_.push_back(s);
  return s;
}

uint64_t Bus::publish(Topic topic, nlohmann::json body, std::shared_ptr<const vision::Scan> scan) {
  std::vector<std::shared_ptr<Subscription>> to;
  BusMessage m{topic, 0, nullptr, std::move(scan)};
  {
    std::lock_guard lock(mu_);
    m.seq = ++seq_;
    body["topic"] = topic_name(topic);
    body["seq"] = m.seq;
    if (topic == Topic::Status) last_status_ = body;
    m.body = std::make_shared<const nlohmann::json>(std::move(body));
    std::erase_if(subs_, [](const auto& w) {
      auto s = w.lock();
      return !s || s->closed();
    });
    for (const auto& w : subs_)
      if (auto s = w.lock(); s && (s->topics() & unsigned(topic))) to.push_back(std::move(s));
  }
  // Outside the bus's lock: a subscriber's queue lock is the only one taken per subscriber, never for long.
  for (const auto& s : to) s->push(m);
  return m.seq;
}

nlohmann::json Bus::last_status() const {
  std::lock_guard lock(mu_);
  return last_status_;
}

size_t Bus::subscribers() const {
  std::lock_guard lock(mu_);
  return size_t(std::count_if(subs_.begin(), subs_.end(), [](const auto& w) { return !w.expired(); }));
}

}  // namespace rbx1::daemon
