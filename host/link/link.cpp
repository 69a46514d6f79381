// link.cpp - the Link's settings, counters and the [link] config table; its other jobs are split by file (README).
#include "link.hpp"

#include <algorithm>
#include <random>

#include "serial_port.hpp"

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

void parse_link_config(rbx1::config::Section link, LinkConfig& out) {
  out.port = link.string("port", out.port);
  if (link.has("port") && out.port.empty()) link.errors().add(link.path() + ".port", "must not be empty");
  int64_t baud = link.integer("baud", out.baud, 1, 4000000);
  if (!supported_baud(static_cast<int>(baud)))
    link.errors().add(link.path() + ".baud", "must be 115200, 230400 or 250000, got " + std::to_string(baud));
  else
    out.baud = static_cast<int>(baud);
  out.timeout_ms = static_cast<int>(link.integer("timeout_ms", out.timeout_ms, 10, 5000));
  out.retries = static_cast<int>(link.integer("retries", out.retries, 0, 20));
  out.heartbeat_ms = static_cast<int>(link.integer("heartbeat_ms", out.heartbeat_ms, 20, 30000));
  out.boot_wait_ms = static_cast<int>(link.integer("boot_wait_ms", out.boot_wait_ms, 0, 10000));
  out.window = static_cast<int>(link.integer("window", out.window, 1, 64));
  link.reject_unknown();
}

Link::Link() {
  std::random_device rd;  // a fresh host starts at a random SEQ so it cannot replay the firmware's last frame
  next_seq_ = static_cast<uint8_t>(rd());
  last_done_ = Clock::now();
}

Link::~Link() { close(); }

void Link::set_timing(int timeout_ms, int retries) {
  std::lock_guard<std::mutex> lock(request_mu_);
  timeout_ms_ = timeout_ms;
  retries_ = retries;
}

void Link::set_window(int max_in_flight) { max_window_ = std::max(1, max_in_flight); }

void Link::set_ahead(int frames) { ahead_ = std::max(0, frames); }

int Link::window() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  if (!hello_.window) return 1;
  return std::min<int>(hello_.window, max_window_);
}

LinkStats Link::stats() const {
  LinkStats s;
  s.requests = counters_.requests;
  s.retransmissions = counters_.retransmissions;
  s.timeouts = counters_.timeouts;
  s.naks = counters_.naks;
  s.stale = counters_.stale;
  s.rejected = counters_.rejected;
  s.link_down = counters_.link_down;
  s.reconnects = counters_.reconnects;
  s.bytes_sent = counters_.bytes_sent;
  s.bytes_received = counters_.bytes_received;
  s.probes = counters_.probes;
  return s;
}

rbx1_hello_resp Link::firmware() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  return hello_;
}

uint8_t Link::next_seq() const {
  std::lock_guard<std::mutex> lock(state_mu_);
  return next_seq_;
}

}  // namespace rbx1::link
