// cmd_daemon.cpp - rbx1 status|scan|pick|home|estop|clear-fault|shutdown: the rbx1d control socket client.
#include <algorithm>
#include <set>
#include <vector>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "command_table.hpp"
#include "error_codes.hpp"
#include "commands.hpp"
#include "control_client.hpp"
#include "job_progress.hpp"

namespace rbx1::cli {

namespace {

struct DaemonOptions {
  std::string socket;
  bool json = false;
  double timeout_s = -1;  // --timeout; < 0: the command's default
  std::string name, place;
};

// How long a command waits for its final line by default: status, estop and shutdown are answered at once (a
// daemon that does not answer them in 10 s is stuck, and the operator must know); jobs take as long as they take.
double default_timeout_s(daemon::Command c) {
  if (c == daemon::Command::Subscribe) return 0;  // streams until the client stops
  return daemon::command_spec(c).mode == daemon::Mode::Immediate ? 10 : 0;
}
}  // namespace

std::string default_socket() {
  const char* env = std::getenv("RBX1_SOCKET");
  return env && *env ? env : control::kDefaultSocket;
}

namespace {

// Codes that mean the request itself was wrong (usage), as opposed to a job that failed.
bool usage_error(const std::string& code) { return daemon::is_request_error(code); }

std::string compact(const nlohmann::json& v) {
  return v.is_string() ? v.get<std::string>() : v.dump();
}

// A plan's waypoints by name, a straight line's segments counted once: "approach x49, descend x3, grip".
std::string waypoint_runs(const nlohmann::json& waypoints) {
  std::string out, last;
  int n = 0;
  auto put = [&] {
    if (n == 0) return;
    out += (out.empty() ? "" : ", ") + last + (n > 1 ? " x" + std::to_string(n) : "");
  };
  for (const auto& w : waypoints) {
    std::string name = w.is_object() ? w.value("name", "?") : "?";
    if (name != last) put(), last = name, n = 0;
    ++n;
  }
  put();
  return out;
}

// One event as a human-readable line: "  1.234 s  event  key=value ...".
void print_event(const nlohmann::json& ev) {
  double t = ev.value("t_ms", 0.0) / 1000.0;
  std::string line;
  for (const auto& [k, v] : ev.items()) {
    if (k == "ts" || k == "t_ms" || k == "event" || k == "detections" || k == "report" || k == "mono_ns") continue;
    line += "  " + k + "=" + (k == "waypoints" && v.is_array() ? waypoint_runs(v) : compact(v));
  }
  std::printf("%8.3f s  %-14s%s\n", t, ev.value("event", "?").c_str(), line.c_str());
  // The scan's detections print as the paper's report (Figure 21).
  if (ev.contains("report") && ev["report"].is_string()) std::fputs(ev["report"].get<std::string>().c_str(), stdout);
  std::fflush(stdout);
}

constexpr int kProgressTickMs = 200;  // the progress line's elapsed time, redrawn while no event comes

// A job's sent/step/step_done lines folded into one line per phase ("moved  approach  49 segments  1.21 s"), for
// people; --verbose (and --json) keep every line.
bool verbose_steps = false;

class PhaseFold {
 public:
  explicit PhaseFold(ProgressLine& progress) : progress_(progress) {}
  // True when ev was folded (nothing to print for it now); prints the finished phase first when one ends.
  bool add(const nlohmann::json& ev) {
    std::string e = ev.value("event", "");
    bool stepwise = e == "sent" || e == "step" || e == "step_done";
    if (verbose_steps) return false;
    if (e == "step_done") {
      std::string name = ev.value("name", "?");
      if (name != name_) {
        flush();
        name_ = name, count_ = 0, t0_ = t1_;
      }
      ++count_;
      t1_ = ev.value("t_ms", 0.0) / 1000.0;
    } else if (!stepwise) {
      flush();
    } else if (name_.empty()) {
      t1_ = ev.value("t_ms", 0.0) / 1000.0;
    }
    return stepwise;
  }
  void flush() {
    if (name_.empty()) return;
    progress_.clear();
    std::printf("%8.3f s  %-14s  %-10s %3d %-8s %6.2f s\n", t1_, "moved", name_.c_str(), count_,
                count_ == 1 ? "segment" : "segments", t1_ - t0_);
    std::fflush(stdout);
    name_.clear();
  }

 private:
  ProgressLine& progress_;
  std::string name_;
  int count_ = 0;
  double t0_ = 0, t1_ = 0;
};

// The final result as "key: value" lines (the report was printed with its event).
void print_result(const nlohmann::json& result) {
  if (result.is_object()) {
    for (const auto& [k, v] : result.items()) {
      if (k == "report" || k == "detections") continue;
      if (k == "warnings" && v.is_array()) {  // what the job did but the user should know (teach: look-alikes)
        for (const auto& w : v) std::fprintf(stderr, "rbx1: warning: %s\n", w.is_string() ? w.get<std::string>().c_str() : w.dump().c_str());
        continue;
      }
      std::printf("%s: %s\n", k.c_str(), compact(v).c_str());
    }
  } else {
    std::printf("%s\n", compact(result).c_str());
  }
}

}  // namespace

// Sends the request and streams its reply. Returns the exit code: 0 ok, 1 job error, 2 usage/connection.
int run_daemon_request(const std::string& socket, bool json, const daemon::Request& request, nlohmann::json* result_out,
                       bool print_final, double timeout_s_option) {
  struct {
    std::string socket;
    bool json;
    double timeout_s;
  } o{socket, json, timeout_s_option};
  control::Client client;
  std::string error;
  if (client.connect(o.socket, error) < 0) {
    std::fprintf(stderr, "rbx1: %s\n", error.c_str());
    return 2;
  }
  if (int r = client.send(request); r < 0) {
    std::fprintf(stderr, "rbx1: %s: cannot send the request: %s (is rbx1d running?)\n", o.socket.c_str(),
                 std::strerror(-r));
    return 2;
  }
  double timeout_s = o.timeout_s >= 0 ? o.timeout_s : default_timeout_s(request.command);
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::string line;
  // A job on a terminal, for people: its progress line, ticking while the job is silent.
  ProgressLine progress(!o.json && !verbose_steps && daemon::command_spec(request.command).mode == daemon::Mode::Job,
                        daemon::command_name(request.command));
  PhaseFold phases(progress);
  for (;;) {
    int wait_ms = -1;
    if (timeout_s > 0)
      wait_ms = int(std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(
                                              deadline - std::chrono::steady_clock::now()).count()));
    const bool tick = progress.on() && (wait_ms < 0 || wait_ms > kProgressTickMs);
    int r = client.read_line(line, tick ? kProgressTickMs : wait_ms);
    if (r == -ETIMEDOUT && tick) {
      progress.draw();
      continue;
    }
    if (r < 0) progress.clear();  // every last word goes on a clean line
    if (r == -ETIMEDOUT) {
      std::fprintf(stderr, "rbx1: %s: no reply within %g s (--timeout)\n", o.socket.c_str(), timeout_s);
      return 2;
    }
    if (r < 0) {
      std::fprintf(stderr, "rbx1: %s: connection closed before the reply ended\n", o.socket.c_str());
      return 2;
    }
    if (o.json) {
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
    }
    nlohmann::json ev = nlohmann::json::parse(line, nullptr, false);
    if (ev.is_discarded() || !ev.is_object()) {
      progress.clear();
      std::fprintf(stderr, "rbx1: unreadable reply line from rbx1d: %s\n", line.substr(0, 200).c_str());
      return 2;
    }
    if (ev.contains("error") || ev.contains("result")) phases.flush(), progress.clear();
    if (ev.contains("error")) {
      const auto& e = ev["error"];
      std::string code = e.value("code", "error");
      if (!o.json) std::fprintf(stderr, "rbx1: %s: %s\n", code.c_str(), e.value("message", "").c_str());
      return usage_error(code) ? 2 : 1;
    }
    if (ev.contains("result")) {
      if (result_out) *result_out = ev["result"];
      if (!o.json && print_final) print_result(ev["result"]);
      return 0;
    }
    if (!o.json && !phases.add(ev)) progress.clear(), print_event(ev);
    progress.add(ev);
  }
}

namespace {

int run(const DaemonOptions& o, const daemon::Request& request) {
  return run_daemon_request(o.socket, o.json, request, nullptr, true, o.timeout_s);
}

CLI::App* add(CLI::App& app, std::shared_ptr<DaemonOptions> o, const std::string& name, const std::string& help) {
  CLI::App* sub = app.add_subcommand(name, help);
  sub->add_option("--socket", o->socket, "rbx1d control socket (default $RBX1_SOCKET or /run/rbx1/rbx1d.sock)");
  sub->add_flag("--json", o->json, "print the raw JSON event lines");
  sub->add_flag("--verbose", verbose_steps, "print every step's sent/step/step_done line, not one line per phase");
  sub->add_option("--timeout", o->timeout_s,
                  "seconds to wait for the final reply line, 0 = no limit (default 10 for status, estop and "
                  "shutdown, no limit for jobs); exit 2 when it passes")
      ->check(CLI::NonNegativeNumber);
  return sub;
}

// A bus line for people: "12:00:01.234  status  ready job=pick joints=[...]" or "events  #7 pick  step ...".
void print_bus_line(const nlohmann::json& ev) {
  std::string topic = ev.value("topic", "");
  std::string ts = ev.value("ts", "");
  std::string when = ts.size() >= 23 ? ts.substr(11, 12) : ts;
  std::string line;
  if (topic == "status") {
    line = std::string(ev.value("ready", false) ? "ready" : "not ready") + "  job=" + compact(ev.value("job", nlohmann::json()));
    if (ev.contains("joints_deg")) line += "  joints_deg=" + ev["joints_deg"].dump();
    if (ev.contains("last_estop")) line += "  last_estop=" + compact(ev["last_estop"]);
  } else if (topic == "scans") {
    const auto& objects = ev.contains("detections") ? ev["detections"].value("objects", nlohmann::json::array())
                                                    : nlohmann::json::array();
    line = std::to_string(objects.size()) + " objects";
    for (const auto& o : objects) line += "  #" + std::to_string(o.value("index", 0)) + " " + compact(o.value("label", nlohmann::json()));
  } else if (topic == "picks") {
    line = "#" + std::to_string(ev.value("id", 0)) + " job " + std::to_string(ev.value("job", 0)) + "  " +
           compact(ev.value("class", nlohmann::json())) + " -> " + compact(ev.value("place", nlohmann::json())) + "  " +
           ev.value("outcome", "?");
    if (auto why = ev.value("reason", nlohmann::json()); why.is_string() && !why.get<std::string>().empty())
      line += " (" + why.get<std::string>() + ")";
  } else if (topic == "events") {
    line = "#" + std::to_string(ev.value("req", 0)) + " " + ev.value("cmd", "?") + "  ";
    if (ev.contains("request")) line += "request " + ev["request"].dump();
    else if (ev.contains("result")) line += "result";
    else if (ev.contains("error")) line += "error " + ev["error"].value("code", "") + ": " + ev["error"].value("message", "");
    else line += ev.value("event", "?");
    for (const auto& [k, v] : ev.items()) {
      static const std::set<std::string> shown{"topic", "seq", "ts", "t_ms", "event", "req", "cmd", "request", "result",
                                               "error", "final", "missed", "detections", "report", "mono_ns"};
      if (!shown.count(k)) line += "  " + k + "=" + compact(v);
    }
  } else {
    line = ev.value("event", "?");
  }
  if (ev.value("missed", 0) > 0) line += "  (missed " + std::to_string(ev.value("missed", 0)) + ")";
  std::printf("%s  %-7s %s\n", when.c_str(), topic.c_str(), line.c_str());
  std::fflush(stdout);
}

// rbx1 watch [--topics status,events,scans,picks]: the bus, one readable line each (--json: the raw lines).
void add_watch_command(CLI::App& app, std::shared_ptr<DaemonOptions> o, int& exit_code) {
  auto topics = std::make_shared<std::vector<std::string>>();
  CLI::App* watch = add(app, o, "watch", daemon::command_spec(daemon::Command::Subscribe).help);
  watch->add_option("--topics", *topics, "status, events, scans, picks (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember({"status", "events", "scans", "picks"}));
  watch->callback([o, topics, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::Subscribe;
    r.topics = *topics;
    control::Client client;
    std::string error;
    if (client.connect(o->socket, error) < 0 || client.send(r) < 0) {
      std::fprintf(stderr, "rbx1: %s\n", error.empty() ? "cannot send the request" : error.c_str());
      exit_code = 2;
      return;
    }
    std::string line;
    while (client.read_line(line, -1) >= 0) {
      nlohmann::json ev = nlohmann::json::parse(line, nullptr, false);
      if (o->json) std::printf("%s\n", line.c_str()), std::fflush(stdout);
      else if (ev.is_object() && ev.contains("error")) std::fprintf(stderr, "rbx1: %s\n", ev["error"].value("message", "").c_str());
      else if (ev.is_object() && ev.contains("topic")) print_bus_line(ev);
      if (ev.is_object() && (ev.contains("error") || ev.contains("result"))) {
        exit_code = ev.contains("error") ? 1 : 0;
        return;
      }
    }
    std::fprintf(stderr, "rbx1: %s: rbx1d closed the connection\n", o->socket.c_str());
    exit_code = 1;
  });
}

}  // namespace

void add_daemon_commands(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<DaemonOptions>();
  o->socket = default_socket();
  // Every request that takes no field is a subcommand of the same name ('_' written '-'), with the table's help.
  for (const auto& spec : daemon::command_table()) {
    if (!spec.fields.empty()) continue;
    std::string name = spec.name;
    std::replace(name.begin(), name.end(), '_', '-');
    daemon::Command command = spec.command;
    add(app, o, name, spec.help)->callback([o, command, &exit_code] {
      daemon::Request r;
      r.command = command;
      exit_code = run(*o, r);
    });
  }
  add_watch_command(app, o, exit_code);
  CLI::App* commands = app.add_subcommand("commands", "list the daemon's requests and error codes (the command table)");
  auto format = std::make_shared<std::string>("text");
  commands->add_option("--format", *format, "text, markdown (the README's table) or json")
      ->check(CLI::IsMember({"text", "markdown", "json"}));
  commands->callback([format] {
    if (*format == "json")
      std::printf("%s\n", nlohmann::json{{"commands", daemon::command_table_json()}, {"errors", daemon::error_codes_json()}}
                               .dump(2).c_str());
    else if (*format == "markdown")
      std::printf("%s\n%s", daemon::command_table_markdown().c_str(), daemon::error_codes_markdown().c_str());
    else
      for (const auto& c : daemon::command_table()) std::printf("%-20s %s\n", c.name, c.help);
  });
  CLI::App* pick = add(app, o, "pick", daemon::command_spec(daemon::Command::Pick).help);
  pick->add_option("name", o->name, "the object's label in the taught library")->required();
  pick->add_option("--place", o->place, "where to put it (a place of the [arm] config)")->required();
  pick->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::Pick;
    r.name = o->name;
    r.place = o->place;
    exit_code = run(*o, r);
  });
}

}  // namespace rbx1::cli
