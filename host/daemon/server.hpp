// server.hpp - the control socket: a Unix stream socket taking one JSON request per line, streaming replies.
#pragma once
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::daemon {

// Where one request's reply goes: event lines, then exactly one final line. Thread-safe; a vanished client
// makes the writes no-ops (the job goes on).
class Reply {
 public:
  Reply(std::shared_ptr<int> fd, Command command);
  // An event line: {"ts": ISO-8601 UTC, "t_ms": ms since the request, "event": name, ...fields}.
  void event(const std::string& name, nlohmann::json fields = nlohmann::json::object());
  void result(nlohmann::json result);
  void error(const std::string& code, const std::string& message);
  bool finished() const { return finished_; }
  Command command() const { return command_; }
  // Also log every line (spdlog, info) prefixed with tag: a job without a client (the start button).
  void log_to(std::string tag) { log_tag_ = std::move(tag); }
  double elapsed_ms() const;

 private:
  void write_line(const nlohmann::json& j);

  std::shared_ptr<int> fd_;
  Command command_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::atomic<bool> finished_{false};
  std::string log_tag_;
};

// UTC wall-clock time as "2026-11-22T01:02:03.456Z".
std::string iso_now();

// Receives every well-formed request on the server thread. It must end the reply (result or error), now or
// later from another thread; it must not block for long (jobs run elsewhere).
using Handler = std::function<void(const Request&, std::shared_ptr<Reply>)>;

class Server {
 public:
  Server() = default;
  ~Server();
  // Binds path (replacing a stale socket file), chmods it to mode. 0 or a negative errno with error set.
  int open(const std::string& path, unsigned mode, std::string& error);
  // Serves until stop(); returns 0.
  int run(const Handler& handler);
  void stop();  // any thread, also a signal handler
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int listen_fd_ = -1;
  int wake_fd_ = -1;
  std::atomic<bool> stopping_{false};
};

}  // namespace rbx1::daemon
