// cmd_daemon.cpp - rbx1 status|scan|pick|home|estop|clear-fault|shutdown: the rbx1d control socket client.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "commands.hpp"
#include "control_client.hpp"

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
  switch (c) {
    case daemon::Command::Status:
    case daemon::Command::Estop:
    case daemon::Command::Shutdown: return 10;
    default: return 0;
  }
}
}  // namespace

std::string default_socket() {
  const char* env = std::getenv("RBX1_SOCKET");
  return env && *env ? env : control::kDefaultSocket;
}

namespace {

// Codes that mean the request itself was wrong (usage), as opposed to a job that failed.
bool usage_error(const std::string& code) {
  return code == "bad_json" || code == "bad_request" || code == "unknown_command" || code == "missing_field" ||
         code == "bad_field" || code == "line_too_long";
}

std::string compact(const nlohmann::json& v) {
  return v.is_string() ? v.get<std::string>() : v.dump();
}

// One event as a human-readable line: "  1.234 s  event  key=value ...".
void print_event(const nlohmann::json& ev) {
  double t = ev.value("t_ms", 0.0) / 1000.0;
  std::string line;
  for (const auto& [k, v] : ev.items()) {
    if (k == "ts" || k == "t_ms" || k == "event" || k == "detections" || k == "report" || k == "mono_ns") continue;
    line += "  " + k + "=" + compact(v);
  }
  std::printf("%8.3f s  %-14s%s\n", t, ev.value("event", "?").c_str(), line.c_str());
  // The scan's detections print as the paper's report (Figure 21).
  if (ev.contains("report") && ev["report"].is_string()) std::fputs(ev["report"].get<std::string>().c_str(), stdout);
  std::fflush(stdout);
}

// The final result as "key: value" lines (the report was printed with its event).
void print_result(const nlohmann::json& result) {
  if (result.is_object()) {
    for (const auto& [k, v] : result.items()) {
      if (k == "report" || k == "detections") continue;
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
    std::fprintf(stderr, "rbx1: %s: send failed (%d)\n", o.socket.c_str(), r);
    return 2;
  }
  double timeout_s = o.timeout_s >= 0 ? o.timeout_s : default_timeout_s(request.command);
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::string line;
  for (;;) {
    int wait_ms = -1;
    if (timeout_s > 0)
      wait_ms = int(std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(
                                              deadline - std::chrono::steady_clock::now()).count()));
    int r = client.read_line(line, wait_ms);
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
      std::fprintf(stderr, "rbx1: unreadable reply line from rbx1d: %s\n", line.substr(0, 200).c_str());
      return 2;
    }
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
    if (!o.json) print_event(ev);
  }
}

namespace {

int run(const DaemonOptions& o, const daemon::Request& request) {
  return run_daemon_request(o.socket, o.json, request, nullptr, true, o.timeout_s);
}

CLI::App* add(CLI::App& app, std::shared_ptr<DaemonOptions> o, const char* name, const char* help) {
  CLI::App* sub = app.add_subcommand(name, help);
  sub->add_option("--socket", o->socket, "rbx1d control socket (default $RBX1_SOCKET or /run/rbx1/rbx1d.sock)");
  sub->add_flag("--json", o->json, "print the raw JSON event lines");
  sub->add_option("--timeout", o->timeout_s,
                  "seconds to wait for the final reply line, 0 = no limit (default 10 for status, estop and "
                  "shutdown, no limit for jobs); exit 2 when it passes")
      ->check(CLI::NonNegativeNumber);
  return sub;
}

}  // namespace

void add_daemon_commands(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<DaemonOptions>();
  o->socket = default_socket();
  struct Simple {
    const char* name;
    const char* help;
    daemon::Command command;
  };
  const Simple simple[] = {
      {"status", "show the daemon's and the arm's state", daemon::Command::Status},
      {"scan", "go to the scan pose, capture and detect; print the report", daemon::Command::Scan},
      {"home", "move the arm to its home pose", daemon::Command::Home},
      {"estop", "emergency stop: halt all motion at once and abort the job", daemon::Command::Estop},
      {"clear-fault", "clear a latched fault (e-stop, heartbeat loss) in the firmware", daemon::Command::ClearFault},
      {"shutdown", "stop rbx1d", daemon::Command::Shutdown},
  };
  for (const auto& s : simple) {
    daemon::Command command = s.command;
    add(app, o, s.name, s.help)->callback([o, command, &exit_code] {
      daemon::Request r;
      r.command = command;
      exit_code = run(*o, r);
    });
  }
  CLI::App* pick = add(app, o, "pick", "pick the named object and put it at a place");
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
