// input_watcher.cpp - debounce, the simulated edge source, and the watcher thread shared by both backends.
#include <algorithm>
#include <cstring>
#include <ctime>

#include <spdlog/spdlog.h>

#include "gpio.hpp"

namespace rbx1::gpio {

int64_t monotonic_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

bool Debouncer::edge(bool level, int64_t t_ns) {
  raw_ = level;
  if (t_ns < until_ns_) {  // inside the window: look again when it ends
    pending_ = true;
    return false;
  }
  if (level == state_) return false;
  state_ = level;
  until_ns_ = t_ns + window_ns_;
  pending_ = false;
  return true;
}

bool Debouncer::settle(int64_t t_ns) {
  if (!pending_ || t_ns < until_ns_) return false;
  pending_ = false;
  if (raw_ == state_) return false;
  state_ = raw_;
  until_ns_ = t_ns + window_ns_;
  return true;
}

void SimEdgeSource::inject(bool level) { inject(level, monotonic_ns()); }

void SimEdgeSource::inject(bool level, int64_t timestamp_ns) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    level_ = level;
    edges_.push_back({level, timestamp_ns});
  }
  cv_.notify_all();
}

int SimEdgeSource::level() {
  std::lock_guard<std::mutex> lock(mu_);
  return level_ ? 1 : 0;
}

int SimEdgeSource::wait(int64_t timeout_ns, std::vector<RawEdge>& out) {
  std::unique_lock<std::mutex> lock(mu_);
  auto ready = [&] { return !edges_.empty() || woken_; };
  if (timeout_ns < 0)
    cv_.wait(lock, ready);
  else
    cv_.wait_for(lock, std::chrono::nanoseconds(timeout_ns), ready);
  woken_ = false;
  out.insert(out.end(), edges_.begin(), edges_.end());
  edges_.clear();
  return 0;
}

void SimEdgeSource::wake() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    woken_ = true;
  }
  cv_.notify_all();
}

InputWatcher::InputWatcher(std::string name, std::unique_ptr<EdgeSource> source, bool active_low, int debounce_ms)
    : name_(std::move(name)), source_(std::move(source)), active_low_(active_low),
      window_ns_(int64_t(debounce_ms) * 1000000) {}

InputWatcher::~InputWatcher() { stop(); }

std::string InputWatcher::describe() const {
  return name_ + " (" + source_->describe() + (active_low_ ? ", active-low" : "") + ", debounce " +
         std::to_string(window_ns_ / 1000000) + " ms)";
}

int InputWatcher::start(InputCallback callback) {
  stop();
  int level = source_->level();
  if (level < 0) return level;
  active_ = (level != 0) != active_low_;
  callback_ = std::move(callback);
  stop_ = false;
  thread_ = std::thread(&InputWatcher::loop, this);
  spdlog::info("gpio {}: watching, now {}", describe(), active_ ? "active" : "inactive");
  return 0;
}

void InputWatcher::stop() {
  stop_ = true;
  if (thread_.joinable()) {
    source_->wake();
    thread_.join();
  }
}

void InputWatcher::loop() {
  Debouncer debounce(window_ns_, active_);
  std::vector<RawEdge> edges;
  auto emit = [&](bool active, int64_t t) {
    active_ = active;
    spdlog::debug("gpio {}: {}", name_, active ? "active" : "inactive");
    if (callback_) callback_(InputEvent{name_, active, t});
  };
  while (!stop_) {
    int64_t deadline = debounce.deadline();
    int64_t timeout = deadline < 0 ? -1 : std::max<int64_t>(0, deadline - monotonic_ns());
    edges.clear();
    int r = source_->wait(timeout, edges);
    if (stop_) break;
    if (r < 0) {
      spdlog::error("gpio {}: {}; no longer watched", name_, std::strerror(-r));
      break;
    }
    for (const RawEdge& e : edges) {
      bool active = e.level != active_low_;
      if (debounce.edge(active, e.timestamp_ns)) emit(active, e.timestamp_ns);
    }
    int64_t now = monotonic_ns();
    if (debounce.deadline() >= 0 && now >= debounce.deadline() && debounce.settle(now)) emit(debounce.state(), now);
  }
}

}  // namespace rbx1::gpio
