// reply.hpp - the request layer shared by every control client (the Unix socket, the web console, tests): one
// Reply per request (event lines, then one final line) written to a sink, and in-process submission.
#pragma once
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "bus.hpp"
#include "request.hpp"

namespace rbx1::daemon {

// Where one request's reply goes: event lines, then exactly one final line. Thread-safe: a job writes its events
// from the worker thread. A sink that has gone (a vanished client) is the sink's business: the job goes on.
class Reply {
 public:
  // Receives each reply line (one JSON document, no newline) in order, with final = true for the last one. It is
  // called with the reply's lock held and must not block (queue the line, never wait for a reader).
  using Sink = std::function<void(const std::string& line, bool final)>;

  // Whether the client is still there (the jog's dead-man rule); null: a client that never goes (start button).
  using Presence = std::function<bool()>;

  // How many bytes written to the sink its client has not taken yet (a subscriber's stream holds back when high);
  // null: the sink never backs up (in-process clients).
  using Backlog = std::function<size_t()>;

  Reply(Sink sink, Command command, Presence presence = nullptr, Backlog backlog = nullptr);
  // A number for this request, unique in the process: the bus's "req", the console log's "#N".
  uint64_t id() const { return id_; }
  // Also publish every line on bus's events topic, with "req", "cmd" and "final" (the daemon does this for every
  // request but reads, so any subscriber sees every client's jobs). Call before the first line.
  void publish_to(Bus& bus, nlohmann::json request);
  size_t backlog() const { return backlog_ ? backlog_() : 0; }
  // An event line: {"ts": ISO-8601 UTC, "t_ms": ms since the request, "event": name, ...fields}.
  void event(const std::string& name, nlohmann::json fields = nlohmann::json::object());
  // A line made elsewhere (a bus message), written as it is: not a final line.
  void forward(const nlohmann::json& line);
  void result(nlohmann::json result);
  void error(ErrorCode code, const std::string& message);
  void error(const Error& e);  // one made elsewhere (the parser's)
  // A code carried as data: a motion result's, an abort reason, the workspace fit's. Literal codes take ErrorCode.
  void error(const std::string& code, const std::string& message);
  bool finished() const { return finished_; }
  // The code of the error that ended the reply (the first one sent); none before an error or after a result.
  std::optional<std::string> error_code() const;
  // Keeps the final line back until release_final() (or the holder's end): a job that writes its records after a
  // failure deep in its steps (a sort's history rows) sends its final line once they are written, so a client
  // that reads them on the final line finds them.
  class FinalHeld {
   public:
    explicit FinalHeld(Reply& r) : r_(r) { r_.hold_final(true); }
    ~FinalHeld() { r_.hold_final(false); }
    FinalHeld(const FinalHeld&) = delete;
    FinalHeld& operator=(const FinalHeld&) = delete;

   private:
    Reply& r_;
  };
  Command command() const { return command_; }
  // Also log every line (spdlog, info) prefixed with tag: a job without a client (the start button).
  void log_to(std::string tag) { log_tag_ = std::move(tag); }
  double elapsed_ms() const;
  // True once the client went away (its connection closed or shut down). A jog whose client is gone is stopped.
  bool client_gone() const { return presence_ && !presence_(); }

 private:
  void write_line(const nlohmann::json& j, bool final);
  void finish(nlohmann::json final_line);
  void hold_final(bool hold);

  Sink sink_;
  Command command_;
  Presence presence_;
  Backlog backlog_;
  uint64_t id_;
  Bus* bus_ = nullptr;
  std::chrono::steady_clock::time_point start_;
  mutable std::mutex mutex_;
  std::atomic<bool> finished_{false};
  bool holding_ = false;                  // FinalHeld
  std::optional<nlohmann::json> held_;  // the final line while held
  std::optional<std::string> error_code_;
  std::string log_tag_;
};

// UTC wall-clock time as "2026-11-22T01:02:03.456Z".
std::string iso_now();

// What the daemon does with a well-formed request (rbx1d: Machine::handle). Called from several threads at once
// (the socket's server thread for estop, its dispatcher thread for the rest, other clients' own threads), so it
// must be thread-safe. It must end the reply (result or error), now or later from another thread, and must not
// block for long (jobs run elsewhere). An estop request is acted on before the handler returns. The immediate
// e-stop entry point without a request is Machine::estop(source).
using Handler = std::function<void(const Request&, std::shared_ptr<Reply>)>;

// One request line (without its newline) from any client: parsed, then given to handler with a Reply writing to
// sink; a malformed line gets its error reply on sink at once and never reaches the handler. Returns the parsed
// command, or nothing for a malformed line.
std::optional<Command> submit_line(const Handler& handler, std::string_view line, Reply::Sink sink,
                                   Reply::Presence presence = nullptr, Reply::Backlog backlog = nullptr);

// An in-process client's view of one reply (the web console, tests): the reply's lines queued as they come.
class ReplyQueue {
 public:
  // A sink that feeds this queue (the queue lives as long as the sink).
  static Reply::Sink sink_for(const std::shared_ptr<ReplyQueue>& q);
  // The next line within timeout_ms (< 0: no limit); false on timeout or when the final line was taken.
  bool next(nlohmann::json& line, int timeout_ms);
  // Every line up to and including the final one; false (with the lines so far) on timeout.
  bool wait_final(std::vector<nlohmann::json>& events, nlohmann::json& final, int timeout_ms);
  bool done() const;  // the final line has arrived

 private:
  void push(const std::string& line, bool final);
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::string> lines_;
  bool final_seen_ = false, final_taken_ = false;
};

// Submits request to handler in-process; its reply lines arrive in the returned queue.
std::shared_ptr<ReplyQueue> submit(const Handler& handler, const Request& request, Reply::Presence presence = nullptr);

}  // namespace rbx1::daemon
