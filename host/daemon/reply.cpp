// reply.cpp - reply lines (events, one final line) to a sink; request submission for every client of the daemon.
#include "reply.hpp"

#include <cmath>
#include <ctime>

#include <spdlog/spdlog.h>

namespace rbx1::daemon {

std::string iso_now() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  tm t{};
  gmtime_r(&ts.tv_sec, &t);
  char buf[40];
  size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &t);
  std::snprintf(buf + n, sizeof buf - n, ".%03ldZ", ts.tv_nsec / 1000000);
  return buf;
}

namespace {
std::atomic<uint64_t> next_request_id{1};
}

Reply::Reply(Sink sink, Command command, Presence presence, Backlog backlog)
    : sink_(std::move(sink)),
      command_(command),
      presence_(std::move(presence)),
      backlog_(std::move(backlog)),
      id_(next_request_id++),
      start_(std::chrono::steady_clock::now()) {}

void Reply::publish_to(Bus& bus, nlohmann::json request) {
  std::lock_guard lock(mutex_);
  bus_ = &bus;
  bus.publish(Topic::Events, {{"req", id_}, {"cmd", command_name(command_)}, {"request", std::move(request)}});
}

double Reply::elapsed_ms() const {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
}

void Reply::write_line(const nlohmann::json& j, bool final) {
  // Replace invalid UTF-8 rather than throw: a file name or label must never kill the daemon.
  std::string line = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (!log_tag_.empty()) spdlog::info("{}: {}", log_tag_, line);
  if (sink_) sink_(line, final);
  if (bus_) {
    nlohmann::json e = j;
    e["req"] = id_;
    e["cmd"] = command_name(command_);
    if (final) e["final"] = true;
    bus_->publish(Topic::Events, std::move(e));
  }
}

void Reply::event(const std::string& name, nlohmann::json fields) {
  std::lock_guard lock(mutex_);
  if (finished_) return;
  nlohmann::json j{{"ts", iso_now()}, {"t_ms", std::round(elapsed_ms() * 10) / 10}, {"event", name}};
  if (fields.is_object())
    for (auto& [k, v] : fields.items()) j[k] = v;
  write_line(j, false);
}

void Reply::forward(const nlohmann::json& line) {
  std::lock_guard lock(mutex_);
  if (!finished_) write_line(line, false);
}

void Reply::result(nlohmann::json result) { finish(result_reply(std::move(result))); }

void Reply::error(const Error& e) {
  {
    std::lock_guard lock(mutex_);
    if (finished_) return;
    error_code_ = e.code;
  }
  finish(error_reply(e));
}

std::optional<std::string> Reply::error_code() const {
  std::lock_guard lock(mutex_);
  return error_code_;
}

void Reply::finish(nlohmann::json final_line) {
  std::lock_guard lock(mutex_);
  if (finished_.exchange(true)) return;
  if (holding_) held_ = std::move(final_line);
  else write_line(final_line, true);
}

void Reply::hold_final(bool hold) {
  std::lock_guard lock(mutex_);
  holding_ = hold;
  if (hold || !held_) return;
  write_line(*held_, true);
  held_.reset();
}

void Reply::error(ErrorCode code, const std::string& message) { error(Error(code, message)); }

void Reply::error(const std::string& code, const std::string& message) {
  Error e;
  e.code = code;
  e.message = message;
  error(e);
}

std::optional<Command> submit_line(const Handler& handler, std::string_view line, Reply::Sink sink,
                                   Reply::Presence presence, Reply::Backlog backlog) {
  Request request;
  Error err;
  if (!parse_request(line, request, err)) {
    spdlog::debug("control: rejected request: {}: {}", err.code, err.message);
    Reply(std::move(sink), Command::Status).error(err);
    return std::nullopt;
  }
  if (request.command != Command::Status) spdlog::info("control: request {}", request_json(request).dump());
  handler(request, std::make_shared<Reply>(std::move(sink), request.command, std::move(presence), std::move(backlog)));
  return request.command;
}

// ---- in-process clients -------------------------------------------------------------------------------------

Reply::Sink ReplyQueue::sink_for(const std::shared_ptr<ReplyQueue>& q) {
  return [q](const std::string& line, bool final) { q->push(line, final); };
}

void ReplyQueue::push(const std::string& line, bool final) {
  {
    std::lock_guard lock(mu_);
    lines_.push_back(line);
    if (final) final_seen_ = true;
  }
  cv_.notify_all();
}

bool ReplyQueue::next(nlohmann::json& line, int timeout_ms) {
  std::unique_lock lock(mu_);
  auto ready = [this] { return !lines_.empty() || final_taken_; };
  if (timeout_ms < 0) cv_.wait(lock, ready);
  else if (!cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), ready)) return false;
  if (lines_.empty()) return false;
  line = nlohmann::json::parse(lines_.front(), nullptr, false);
  lines_.pop_front();
  if (final_seen_ && lines_.empty()) final_taken_ = true;
  return true;
}

bool ReplyQueue::wait_final(std::vector<nlohmann::json>& events, nlohmann::json& final, int timeout_ms) {
  auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  nlohmann::json line;
  for (;;) {
    int left = timeout_ms < 0 ? -1
                              : int(std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(
                                                             deadline - std::chrono::steady_clock::now())
                                                             .count()));
    if (!next(line, left)) return false;
    if (line.is_object() && (line.contains("result") || line.contains("error"))) {
      final = std::move(line);
      return true;
    }
    events.push_back(std::move(line));
  }
}

bool ReplyQueue::done() const {
  std::lock_guard lock(mu_);
  return final_seen_;
}

std::shared_ptr<ReplyQueue> submit(const Handler& handler, const Request& request, Reply::Presence presence) {
  auto q = std::make_shared<ReplyQueue>();
  handler(request, std::make_shared<Reply>(ReplyQueue::sink_for(q), request.command, std::move(presence)));
  return q;
}

}  // namespace rbx1::daemon
