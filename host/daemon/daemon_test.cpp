// daemon_test.cpp - request parsing, the control socket (framing, limits, error replies, mode), [daemon] config,
// and the start button driving a Machine against rbx1-simfw.

#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include "control_client.hpp"
#include "daemon_config.hpp"
#include "daemon_setup.hpp"
#include "machine.hpp"
#include "request.hpp"
#include "server.hpp"

using namespace rbx1;
using namespace rbx1::daemon;

static std::string parse_error(const std::string& line) {
  Request r;
  Error e;
  EXPECT_FALSE(parse_request(line, r, e)) << line;
  return e.code;
}

TEST(Request, ParsesEveryCommand) {
  const std::pair<const char*, Command> cases[] = {
      {"status", Command::Status},       {"scan", Command::Scan},   {"home", Command::Home},
      {"estop", Command::Estop},         {"shutdown", Command::Shutdown},
      {"clear_fault", Command::ClearFault}};
  for (auto [name, cmd] : cases) {
    Request r;
    Error e;
    ASSERT_TRUE(parse_request(std::string("{\"cmd\":\"") + name + "\"}", r, e)) << name << e.message;
    EXPECT_EQ(r.command, cmd);
  }
  Request r;
  Error e;
  ASSERT_TRUE(parse_request(R"({"cmd":"pick","name":"bolt","place":"tray"})", r, e));
  EXPECT_EQ(r.command, Command::Pick);
  EXPECT_EQ(r.name, "bolt");
  EXPECT_EQ(r.place, "tray");
  EXPECT_EQ(request_json(r).dump(), R"({"cmd":"pick","name":"bolt","place":"tray"})");
}

TEST(Request, RejectsMalformedLines) {
  EXPECT_EQ(parse_error("{"), "bad_json");
  EXPECT_EQ(parse_error("hello"), "bad_json");
  EXPECT_EQ(parse_error("[1,2]"), "bad_request");
  EXPECT_EQ(parse_error("\"status\""), "bad_request");
  EXPECT_EQ(parse_error("{}"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":5})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"dance"})"), "unknown_command");
  EXPECT_EQ(parse_error(R"({"cmd":"pick","name":"bolt"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"pick","place":"tray"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"pick","name":"","place":"tray"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"pick","name":7,"place":"tray"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"pick","name":"a\u0001b","place":"tray"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"status","name":"x"})"), "bad_field");
  EXPECT_EQ(parse_error(std::string(kMaxRequestLine + 1, ' ')), "line_too_long");
  EXPECT_EQ(parse_error("\xff\xfe"), "bad_json");
}

class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = "/tmp/rbx1-daemon-test-" + std::to_string(getpid()) + ".sock";
    std::string error;
    ASSERT_EQ(server_.open(path_, 0660, error), 0) << error;
    thread_ = std::thread([this] {
      server_.run([this](const Request& r, std::shared_ptr<Reply> reply) {
        ++handled_;
        if (r.command == Command::Scan) reply->event("step", {{"n", 1}});
        reply->result({{"cmd", command_name(r.command)}, {"name", r.name}});
      });
    });
  }
  void TearDown() override {
    server_.stop();
    thread_.join();
  }
  nlohmann::json roundtrip(control::Client& c, const std::string& line) {
    EXPECT_EQ(c.send_line(line), 0);
    std::string reply;
    EXPECT_EQ(c.read_line(reply, 2000), 0);
    return nlohmann::json::parse(reply);
  }
  std::string path_;
  Server server_;
  std::thread thread_;
  std::atomic<int> handled_{0};
};

TEST_F(ServerTest, SocketModeIs0660) {
  struct stat st {};
  ASSERT_EQ(::stat(path_.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);
}

TEST_F(ServerTest, StreamsEventsThenOneFinalLine) {
  control::Client c;
  std::string error;
  ASSERT_EQ(c.connect(path_, error), 0) << error;
  Request r;
  r.command = Command::Scan;
  ASSERT_EQ(c.send(r), 0);
  std::string line;
  ASSERT_EQ(c.read_line(line, 2000), 0);
  auto ev = nlohmann::json::parse(line);
  EXPECT_EQ(ev["event"], "step");
  EXPECT_EQ(ev["n"], 1);
  EXPECT_TRUE(ev["ts"].is_string());
  EXPECT_TRUE(ev["t_ms"].is_number());
  EXPECT_FALSE(control::is_final(ev));
  ASSERT_EQ(c.read_line(line, 2000), 0);
  auto fin = nlohmann::json::parse(line);
  EXPECT_TRUE(control::is_final(fin));
  EXPECT_EQ(fin["result"]["cmd"], "scan");
}

TEST_F(ServerTest, MalformedLinesGetErrorsAndTheConnectionSurvives) {
  control::Client c;
  std::string error;
  ASSERT_EQ(c.connect(path_, error), 0) << error;
  EXPECT_EQ(roundtrip(c, "not json")["error"]["code"], "bad_json");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"fly"})")["error"]["code"], "unknown_command");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"pick"})")["error"]["code"], "missing_field");
  EXPECT_EQ(roundtrip(c, std::string(100000, 'x'))["error"]["code"], "line_too_long");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"pick","name":"bolt","place":"tray"})")["result"]["name"], "bolt");
  EXPECT_EQ(handled_, 1);
}

TEST_F(ServerTest, ServesManyClientsConnectingAtOnce) {
  // Connections accepted while others are served must be polled from the next round on (a past bug read
  // their events from beyond the poll array and dropped them).
  std::vector<std::unique_ptr<control::Client>> clients;
  for (int i = 0; i < 20; ++i) {
    auto c = std::make_unique<control::Client>();
    std::string error;
    ASSERT_EQ(c->connect(path_, error), 0) << error;
    ASSERT_EQ(c->send_line(R"({"cmd":"home"})"), 0);
    clients.push_back(std::move(c));
  }
  for (auto& c : clients) {
    std::string line;
    ASSERT_EQ(c->read_line(line, 2000), 0);
    EXPECT_EQ(nlohmann::json::parse(line)["result"]["cmd"], "home");
  }
  EXPECT_EQ(handled_, 20);
}

TEST_F(ServerTest, ReplacesAStaleSocketButNotALiveOne) {
  Server second;
  std::string error;
  EXPECT_EQ(second.open(path_, 0660, error), -EADDRINUSE);
  EXPECT_NE(error.find("another rbx1d"), std::string::npos) << error;
}

TEST(ClientTest, ConnectErrorNamesThePath) {
  control::Client c;
  std::string error;
  EXPECT_LT(c.connect("/tmp/rbx1-no-such-daemon.sock", error), 0);
  EXPECT_NE(error.find("/tmp/rbx1-no-such-daemon.sock"), std::string::npos);
}

TEST(DaemonConfig, DefaultsAndErrorsNameTheKey) {
  config::Errors errors;
  auto table = config::parse_text(R"(
socket = "/tmp/x.sock"
socket_mode = 0o600
home_on_start = "jump"
log_level = "loud"
move_timeout_s = -1
colour = "red"
)", errors);
  ASSERT_TRUE(errors.ok()) << errors.joined();
  DaemonConfig d;
  parse_daemon_config(config::Section(&table, "daemon", errors), d);
  EXPECT_EQ(d.socket, "/tmp/x.sock");
  EXPECT_EQ(d.socket_mode, 0600u);
  std::string all = errors.joined();
  EXPECT_EQ(errors.messages().size(), 4u) << all;
  EXPECT_NE(all.find("daemon.home_on_start"), std::string::npos);
  EXPECT_NE(all.find("daemon.log_level"), std::string::npos);
  EXPECT_NE(all.find("daemon.move_timeout_s"), std::string::npos);
  EXPECT_NE(all.find("daemon.colour: unknown key"), std::string::npos);
}

TEST(DaemonConfig, StartPickAndPlace) {
  config::Errors errors;
  auto table = config::parse_text("start_pick = \"bo\\u0001lt\"\nstart_place = \"\"\n", errors);
  ASSERT_TRUE(errors.ok()) << errors.joined();
  DaemonConfig d;
  parse_daemon_config(config::Section(&table, "daemon", errors), d);
  std::string all = errors.joined();
  EXPECT_EQ(errors.messages().size(), 2u) << all;
  EXPECT_NE(all.find("daemon.start_pick"), std::string::npos) << all;
  EXPECT_NE(all.find("daemon.start_place"), std::string::npos) << all;

  config::Errors ok_errors;
  auto empty = config::parse_text("", ok_errors);
  DaemonConfig defaults;
  parse_daemon_config(config::Section(&empty, "daemon", ok_errors), defaults);
  EXPECT_TRUE(ok_errors.ok()) << ok_errors.joined();
  EXPECT_EQ(defaults.start_pick, "");
  EXPECT_EQ(defaults.start_place, "tray");
}

extern char** environ;

namespace {

// [gpio] start_button without [daemon] start_pick, and a start_place the arm does not know, name their keys.
TEST(DaemonStartButtonConfig, ErrorsNameTheKeys) {
  auto dir = std::filesystem::temp_directory_path() / ("rbx1-start-button-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  auto load = [&](const std::string& text) {
    auto file = dir / "rbx1.toml";
    std::ofstream(file) << text;
    Config c;
    config::Errors errors;
    Overrides o;
    o.port = "/dev/null";
    load_config(file.string(), o, c, errors);
    return errors.joined();
  };
  std::string a = load("[camera]\ndevice = \"x.png\"\n[gpio]\nstart_button = { line = \"27\", chip = \"gpiochip0\" }\n");
  EXPECT_NE(a.find("daemon.start_pick: must name the object"), std::string::npos) << a;
  std::string b = load("[camera]\ndevice = \"x.png\"\n[daemon]\nstart_pick = \"bolt\"\nstart_place = \"shelf\"\n");
  EXPECT_NE(b.find("daemon.start_place: no place \"shelf\""), std::string::npos) << b;
  EXPECT_EQ(b.find("daemon.start_pick"), std::string::npos) << b;
  std::string c = load("[camera]\ndevice = \"x.png\"\n[daemon]\nstart_place = \"shelf\"\n");  // no button job: unused
  EXPECT_EQ(c, "");
  std::filesystem::remove_all(dir);
}

// rbx1-simfw behind its pty, a child process for the test's lifetime.
class Simfw {
 public:
  Simfw() {
    int out[2];
    if (pipe(out) < 0) return;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, out[1], 1);
    posix_spawn_file_actions_addclose(&fa, out[0]);
    char* argv[] = {const_cast<char*>(RBX1_SIMFW_BIN), nullptr};
    if (posix_spawn(&pid_, RBX1_SIMFW_BIN, &fa, nullptr, argv, environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&fa);
    ::close(out[1]);
    char c;
    while (pid_ > 0 && ::read(out[0], &c, 1) == 1 && c != '\n') port_ += c;
    out_ = out[0];
  }
  ~Simfw() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
    if (out_ >= 0) ::close(out_);
  }
  const std::string& port() const { return port_; }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string port_;
};

// One request through Machine::handle, its reply read from a socketpair until the final line.
nlohmann::json call(Machine& m, Command c) {
  int sv[2];
  if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) < 0) return nullptr;
  auto fd = std::shared_ptr<int>(new int(sv[0]), [](int* p) { ::close(*p); delete p; });
  Request r;
  r.command = c;
  m.handle(r, std::make_shared<Reply>(fd, c));
  std::string buf;
  char chunk[4096];
  nlohmann::json out;
  for (;;) {
    size_t nl = buf.find('\n');
    if (nl != std::string::npos) {
      auto j = nlohmann::json::parse(buf.substr(0, nl), nullptr, false);
      buf.erase(0, nl + 1);
      if (control::is_final(j)) {
        out = j;
        break;
      }
      continue;
    }
    ssize_t n = ::read(sv[1], chunk, sizeof chunk);
    if (n <= 0) break;
    buf.append(chunk, size_t(n));
  }
  ::close(sv[1]);
  return out;
}

// Waits up to timeout_ms for the status reply's "job" to satisfy pred.
template <class Pred>
bool wait_job(Machine& m, Pred pred, int timeout_ms) {
  for (int t = 0; t < timeout_ms; t += 10) {
    auto st = call(m, Command::Status);
    if (st.is_object() && st.contains("result") && pred(st["result"]["job"])) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

size_t count_lines(const std::vector<std::string>& lines, const std::string& needle) {
  size_t n = 0;
  for (const auto& l : lines) n += l.find(needle) != std::string::npos;
  return n;
}

}  // namespace

// The simulated start button (active-low, debounced by the same InputWatcher as the e-stop) starts the configured
// pick on an idle daemon; its events go to the log; a press while it runs is ignored and queues nothing.
TEST(DaemonStartButton, PressRunsTheConfiguredPickOnce) {
  Simfw sim;
  ASSERT_FALSE(sim.port().empty()) << RBX1_SIMFW_BIN << " printed no pty path";
  auto ring = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(5000);
  auto previous = spdlog::default_logger();
  spdlog::set_default_logger(std::make_shared<spdlog::logger>("test", ring));
  spdlog::set_pattern("%v");

  Config config;
  config::Errors errors;
  Overrides o;
  o.port = sim.port();
  ASSERT_TRUE(load_config(RBX1_DATA_DIR "/rbx1.toml", o, config, errors)) << errors.joined();
  config.daemon.start_pick = "l_shape";
  config.daemon.start_place = "tray";
  config.gpio.start_button.active_low = true;
  config.gpio.start_button.debounce_ms = 10;
  auto source = std::make_unique<gpio::SimEdgeSource>(true);  // active-low: released reads 1
  gpio::SimEdgeSource* button = source.get();
  {
    Machine machine(config, nullptr, std::move(source));
    std::string error;
    ASSERT_EQ(machine.start(error), 0) << error;
    bool ready = false;
    for (int i = 0; i < 200 && !ready; ++i) {
      auto st = call(machine, Command::Status);
      ready = st.is_object() && st["result"].value("ready", false);
      if (!ready) std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    ASSERT_TRUE(ready);
    EXPECT_TRUE(wait_job(machine, [](const nlohmann::json& j) { return j.is_null(); }, 100));

    button->inject(false);  // pressed
    ASSERT_TRUE(wait_job(machine, [](const nlohmann::json& j) { return j == "pick"; }, 3000))
        << "the press started no job";
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    button->inject(true);  // released
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    button->inject(false);  // pressed again while the pick runs
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    button->inject(true);
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    auto st = call(machine, Command::Status);
    EXPECT_EQ(st["result"]["job"], "pick") << st.dump();
    // A client's request meanwhile is refused as busy, as for any job.
    auto busy = call(machine, Command::Home);
    EXPECT_EQ(busy["error"]["code"], "busy") << busy.dump();

    machine.estop("test");  // end the pick quickly; the worker must not start a queued second one
    ASSERT_TRUE(wait_job(machine, [](const nlohmann::json& j) { return j.is_null(); }, 5000));
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    EXPECT_TRUE(wait_job(machine, [](const nlohmann::json& j) { return j.is_null(); }, 50));
    machine.stop();
  }
  auto lines = ring->last_formatted();
  spdlog::set_default_logger(previous);
  std::string all;
  for (const auto& l : lines) all += l + "\n";
  EXPECT_EQ(count_lines(lines, "start button: pick l_shape --place tray"), 1u) << all;
  EXPECT_EQ(count_lines(lines, "\"event\":\"job_started\""), 1u) << all;
  EXPECT_EQ(count_lines(lines, R"("event":"job_started","name":"l_shape","place":"tray")"), 1u) << all;
  EXPECT_EQ(count_lines(lines, "pressed while a job is running (pick); ignored"), 1u) << all;
  EXPECT_EQ(count_lines(lines, "\"event\":\"captured\""), 0u) << all;  // stopped on the way to the scan pose
  EXPECT_EQ(count_lines(lines, R"(start button: {"error":{"code":"estop")"), 1u) << all;
}
