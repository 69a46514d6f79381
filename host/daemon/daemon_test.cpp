// daemon_test.cpp - request parsing, [daemon] config, and the start button driving a Machine against rbx1-simfw
// (the control socket's tests are in server_test.cpp).

#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include "command_table.hpp"
#include "control_client.hpp"
#include "daemon_config.hpp"
#include "daemon_setup.hpp"
#include "error_codes.hpp"
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

TEST(DaemonConfig, PickCheck) {
  config::Errors errors;
  auto table = config::parse_text("verify_pick = true\npick_retries = 2\n", errors);
  DaemonConfig d;
  parse_daemon_config(config::Section(&table, "daemon", errors), d);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_TRUE(d.verify_pick);
  EXPECT_EQ(d.pick_retries, 2);
  config::Errors bad_errors;
  auto bad = config::parse_text("verify_pick = 1\npick_retries = 4\n", bad_errors);
  DaemonConfig b;
  parse_daemon_config(config::Section(&bad, "daemon", bad_errors), b);
  std::string all = bad_errors.joined();
  EXPECT_EQ(bad_errors.messages().size(), 2u) << all;
  EXPECT_NE(all.find("daemon.verify_pick"), std::string::npos) << all;
  EXPECT_NE(all.find("daemon.pick_retries"), std::string::npos) << all;
  DaemonConfig defaults;
  EXPECT_FALSE(defaults.verify_pick);
  EXPECT_EQ(defaults.pick_retries, 1);
}

// [daemon] arm_id names the arm outside: the host name by default; [mqtt] prefix and client_id follow it.
TEST(DaemonConfig, ArmIdAndTheMqttTable) {
  auto dir = std::filesystem::temp_directory_path() / ("rbx1-arm-id-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  auto load = [&](const std::string& text, Config& c) {
    auto file = dir / "rbx1.toml";
    std::ofstream(file) << "[camera]\ndevice = \"x.png\"\n" << text;
    config::Errors errors;
    Overrides o;
    o.port = "/dev/null";
    load_config(file.string(), o, c, errors);
    return errors.joined();
  };
  Config c;
  EXPECT_EQ(load("[daemon]\narm_id = \"cell-a\"\n[mqtt]\nenabled = true\nusername = \"cell-a\"\n"
                 "password_file = \"mqtt.pw\"\n", c), "");
  EXPECT_EQ(c.mqtt.prefix, "rbx1/cell-a");
  EXPECT_EQ(c.mqtt.client_id, "cell-a");
  EXPECT_EQ(c.mqtt.password_file, (dir / "mqtt.pw").string());  // relative to the config file
  Config d;
  EXPECT_EQ(load("", d), "");
  EXPECT_EQ(d.daemon.arm_id, default_arm_id());
  EXPECT_FALSE(d.daemon.arm_id.empty());
  Config e;
  std::string bad = load("[daemon]\narm_id = \"a/b\"\n", e);
  EXPECT_EQ(bad.rfind("daemon.arm_id: must be 1..64 letters", 0), 0u) << bad;
  std::filesystem::remove_all(dir);
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


// A state directory of this test run's own: a Machine opens its history there.
std::string test_state_dir() {
  return (std::filesystem::temp_directory_path() / ("rbx1_daemon_test_" + std::to_string(::getpid()))).string();
}

// Waits up to timeout_ms for the status reply's "job" to satisfy pred.
template <class Pred>
bool wait_job(Machine& m, Pred pred, int timeout_ms) {
  for (int t = 0; t < timeout_ms; t += 10) {
    auto st = m.call(Command::Status);
    if (st.is_object() && st.contains("result") && pred(st["result"]["job"])) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// Waits up to timeout_ms for the status reply to say ready.
bool wait_ready(Machine& m, int timeout_ms = 5000) {
  for (int t = 0; t < timeout_ms; t += 25) {
    auto st = m.call(Command::Status);
    if (st.is_object() && st["result"].value("ready", false)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
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
  o.state_dir = test_state_dir();  // never the machine's /var/lib/rbx1
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
    ASSERT_TRUE(wait_ready(machine));
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
    auto st = machine.call(Command::Status);
    EXPECT_EQ(st["result"]["job"], "pick") << st.dump();
    // A client's request meanwhile is refused as busy, as for any job.
    auto busy = machine.call(Command::Home);
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

// The host's GPIO e-stop path during a pick: an edge on the e-stop line (the simulated backend behind the same
// InputWatcher as libgpiod's) puts ESTOP on the wire (the firmware latches ESTOP_COMMAND, which only an ESTOP frame
// sets; its own input would set ESTOP_INPUT), aborts the job with an `estop` event naming gpio and error `estop`,
// and the arm stands short of the move's target; jobs are refused until the line is released and the fault cleared.
// The status LED (a simulated output line) is lit exactly while the daemon is ready.
TEST(DaemonGpioEstop, EdgeDuringAPickStopsTheArmAndAbortsTheJob) {
  Simfw sim;
  ASSERT_FALSE(sim.port().empty()) << RBX1_SIMFW_BIN << " printed no pty path";
  Config config;
  config::Errors errors;
  Overrides o;
  o.port = sim.port();
  o.state_dir = test_state_dir();  // never the machine's /var/lib/rbx1
  ASSERT_TRUE(load_config(RBX1_DATA_DIR "/rbx1.toml", o, config, errors)) << errors.joined();
  config.gpio.estop.active_low = false;
  config.gpio.estop.debounce_ms = 5;
  auto source = std::make_unique<gpio::SimEdgeSource>(false);
  gpio::SimEdgeSource* line = source.get();
  auto led_line = std::make_unique<gpio::SimOutputLine>();
  gpio::SimOutputLine* led = led_line.get();
  Machine machine(config, std::move(source), nullptr, std::move(led_line));
  std::string error;
  ASSERT_EQ(machine.start(error), 0) << error;
  EXPECT_GE(led->writes(), 1) << "the LED was not put in a known state at start";
  ASSERT_TRUE(wait_ready(machine));
  EXPECT_TRUE(led->value()) << "the status LED is dark while the daemon is ready";

  Handler handler = [&machine](const Request& r, std::shared_ptr<Reply> reply) { machine.handle(r, std::move(reply)); };
  Request pick;
  pick.command = Command::Pick;
  pick.name = "l_shape";
  pick.place = "tray";
  auto q = submit(handler, pick);
  nlohmann::json ev, moving;
  while (q->next(ev, 10000)) {
    ASSERT_FALSE(control::is_final(ev)) << "the pick ended before it moved: " << ev.dump();
    if (ev.value("event", "") == "step" && ev.value("kind", "") == "move") {
      moving = ev;
      break;
    }
  }
  ASSERT_TRUE(moving.is_object()) << "no move started within 10 s";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // under way, far from its end at 20 deg/s
  line->inject(true);                                          // the e-stop pressed

  std::vector<nlohmann::json> events;
  nlohmann::json final;
  ASSERT_TRUE(q->wait_final(events, final, 5000)) << "the job did not end within 5 s of the e-stop edge";
  EXPECT_FALSE(led->value()) << "the status LED stays lit after the e-stop";
  EXPECT_EQ(final["error"]["code"], "estop") << final.dump();
  size_t estop_events = 0, done_after = 0;
  for (const auto& e : events) {
    if (e.value("event", "") == "estop") {
      ++estop_events;
      EXPECT_EQ(e["source"], "gpio") << e.dump();
    }
    if (e.value("event", "") == "step_done" && e.value("step", 0) >= moving.value("step", 0)) ++done_after;
  }
  EXPECT_EQ(estop_events, 1u);
  EXPECT_EQ(done_after, 0u) << "the interrupted move was reported done";

  // Latched: FAULT with ESTOP_COMMAND, and the arm no longer moves (the idle STATUS refreshes the cache).
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  auto st1 = machine.call(Command::Status)["result"];
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  auto st2 = machine.call(Command::Status)["result"];
  ASSERT_TRUE(st2["firmware"].is_object()) << st2.dump();
  EXPECT_EQ(st2["firmware"]["state"], "FAULT") << st2.dump();
  auto faults = st2["firmware"]["faults"];
  EXPECT_NE(std::find(faults.begin(), faults.end(), "ESTOP_COMMAND"), faults.end()) << st2.dump();
  EXPECT_EQ(std::find(faults.begin(), faults.end(), "ESTOP_INPUT"), faults.end()) << st2.dump();
  EXPECT_EQ(st1["firmware"]["position"], st2["firmware"]["position"]) << "the arm still moves after the e-stop";
  EXPECT_NE(st2["firmware"]["position"], moving["target"]) << "the interrupted move completed";
  EXPECT_EQ(st2["last_estop"], "gpio");
  EXPECT_EQ(st2["ready"], false);

  auto home = machine.call(Command::Home);
  std::string code = home["error"].value("code", "");
  EXPECT_TRUE(code == "fault" || code == "estop") << home.dump();
  line->inject(false);  // released
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  auto cleared = machine.call(Command::ClearFault);
  EXPECT_EQ(cleared["result"]["cleared"], true) << cleared.dump();
  for (int i = 0; i < 100 && !led->value(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(led->value()) << "the status LED did not come back on after clear_fault";
  EXPECT_EQ(machine.call(Command::Status)["result"]["ready"], true);
  machine.stop();
  EXPECT_FALSE(led->value()) << "the status LED stays lit after the daemon stopped";
}

TEST(CommandTable, EveryCommandHasOneEntryAndRoundTrips) {
  std::set<std::string> names;
  for (int c = int(Command::Status); c <= int(Command::Recipes); ++c) {  // Recipes: the last of the enum
    const CommandSpec& spec = command_spec(Command(c));
    EXPECT_EQ(spec.command, Command(c)) << "Command " << c << " has no command_table entry";
    EXPECT_TRUE(names.insert(spec.name).second) << spec.name;
    EXPECT_EQ(find_command(spec.name), &spec);
    EXPECT_STRNE(spec.help, "");
  }
  EXPECT_EQ(names.size(), command_table().size());
  // Each request the table describes, written by the client and read back by the daemon, is the same request.
  for (const char* line : {R"({"cmd":"pick","name":"bolt","place":"tray"})", R"({"cmd":"jog","joint":3,"deg":-2.5})",
                           R"({"cmd":"jog","mm":[0,0,-1]})", R"({"cmd":"teach","index":2,"name":"nut"})",
                           R"({"cmd":"calibrate_workspace","action":"record","marker":0})",
                           R"({"cmd":"subscribe","topics":["status","scans"]})", R"({"cmd":"background","frames":4})"}) {
    Request r;
    Error e;
    ASSERT_TRUE(parse_request(line, r, e)) << line << ": " << e.message;
    EXPECT_EQ(request_json(r), nlohmann::json::parse(line)) << line;
  }
}

TEST(CommandTable, FieldsAreCheckedAsDeclared) {
  EXPECT_EQ(parse_error(R"({"cmd":"subscribe","topics":["status","weather"]})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"subscribe","topics":[]})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"subscribe","topics":"status"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"home","speed":2})"), "bad_field");
  Request r;
  Error e;
  ASSERT_TRUE(parse_request(R"({"cmd":"subscribe"})", r, e));
  EXPECT_TRUE(r.topics.empty());
  // Who may call what, as the console and MQTT read it.
  EXPECT_EQ(command_spec(Command::Status).access, Access::Read);
  EXPECT_EQ(command_spec(Command::Estop).access, Access::Estop);
  EXPECT_EQ(command_spec(Command::Pick).access, Access::Act);
  EXPECT_EQ(command_spec(Command::Shutdown).access, Access::Local);
  EXPECT_EQ(command_spec(Command::Pick).mode, Mode::Job);
  EXPECT_EQ(command_spec(Command::Estop).mode, Mode::Immediate);
}

TEST(ErrorCodes, OneListClassifiesEveryCode) {
  for (const char* c : {"bad_json", "bad_request", "unknown_command", "missing_field", "bad_field", "line_too_long"})
    EXPECT_TRUE(is_request_error(c)) << c;
  for (const char* c : {"busy", "not_ready", "object_absent", "estop", "link_down", "timeout"}) {
    EXPECT_FALSE(is_request_error(c)) << c;
    EXPECT_NE(find_error(c), nullptr) << c;
  }
  EXPECT_EQ(find_error("made_up"), nullptr);
  std::set<std::string> codes;
  for (const auto& e : error_codes()) EXPECT_TRUE(codes.insert(e.code).second) << e.code;
}

// ---- the spine's typed seams: handlers by table, readiness, the firmware-reset check, errors in words -----------

TEST(CommandHandlers, EveryCommandHasOneOfItsMode) {
  for (const auto& spec : command_table()) {
    bool job = Machine::job_handler(spec.command) != nullptr;
    bool immediate = Machine::immediate_handler(spec.command) != nullptr;
    EXPECT_EQ(job, spec.mode == Mode::Job) << spec.name << ": a job needs its line in job_handler";
    EXPECT_EQ(immediate, spec.mode == Mode::Immediate) << spec.name << ": needs its line in immediate_handler";
  }
  EXPECT_EQ(Machine::job_handler(Command::Status), nullptr);
  EXPECT_EQ(Machine::immediate_handler(Command::Pick), nullptr);
}

TEST(Readiness, StatesAndTheirReasons) {
  ReadyState r;
  EXPECT_EQ(r.state(), Readiness::Starting);
  EXPECT_FALSE(r.ready());
  EXPECT_EQ(r.reason(), "");
  r.prepared({Readiness::LinkDown, "/dev/rbx1: STATUS failed: no answer"});
  EXPECT_EQ(r.state(), Readiness::LinkDown);
  EXPECT_EQ(r.reason(), "/dev/rbx1: STATUS failed: no answer");
  EXPECT_EQ(job_error(r.state()), ErrorCode::NotReady);
  r.prepared({Readiness::Fault, "firmware in FAULT [\"ESTOP_COMMAND\"] (rbx1 clear-fault)"});
  EXPECT_EQ(job_error(r.state()), ErrorCode::Fault);
  r.prepared({Readiness::Ready, "ignored"});
  EXPECT_TRUE(r.ready());
  EXPECT_EQ(r.reason(), "");  // a ready state has no reason
  EXPECT_STREQ(readiness_name(r.state()), "ready");
}

TEST(Readiness, AHoldOutlastsEveryPreparationUntilReleased) {
  ReadyState r;
  r.prepared({Readiness::Ready, ""});
  r.hold("the firmware lost its joint positions (reset?)");
  EXPECT_TRUE(r.held());
  EXPECT_FALSE(r.ready());
  EXPECT_EQ(r.reason(), "the firmware lost its joint positions (reset?): put the arm at its home pose, then rbx1 clear-fault");
  EXPECT_EQ(job_error(r.state()), ErrorCode::NotReady);
  r.prepared({Readiness::Ready, ""});  // a preparation racing the hold does not end it
  r.prepared({Readiness::LinkDown, "gone"});
  EXPECT_TRUE(r.held());
  EXPECT_NE(r.reason().find("rbx1 clear-fault"), std::string::npos);
  r.release();  // clear_fault
  EXPECT_EQ(r.state(), Readiness::Starting);
  EXPECT_EQ(r.reason(), "");
  r.prepared({Readiness::Ready, ""});
  EXPECT_TRUE(r.ready());
}

TEST(FirmwareReset, OneCheckForPositionsLostAndCountersBack) {
  rbx1_status_resp before{}, now{};
  before.homed = now.homed = RBX1_ALL_JOINTS_MASK;
  before.moves_accepted = 10, before.moves_done = 8, before.moves_flushed = 1;
  now = before;
  now.moves_accepted = 12, now.moves_done = 12;
  EXPECT_EQ(firmware_reset(&before, now), "");
  EXPECT_EQ(firmware_reset(nullptr, now), "");
  now.homed = RBX1_ALL_JOINTS_MASK & ~1u;  // joint 1 forgot its position
  EXPECT_EQ(firmware_reset(&before, now), "the firmware lost its joint positions (reset?)");
  EXPECT_EQ(firmware_reset(nullptr, now), "the firmware lost its joint positions (reset?)");
  now = before;
  now.moves_done = 0;  // counters restarted: a power-cycled board (homed again by someone) or another one
  EXPECT_EQ(firmware_reset(&before, now), "the firmware's counters went back (reset?)");
  now.homed = 0;  // both: the counters are named first
  EXPECT_EQ(firmware_reset(&before, now), "the firmware's counters went back (reset?)");
  before.moves_accepted = 65535, now = before;
  now.moves_accepted = 2;  // the 16-bit counter wrapped: not a reset
  EXPECT_EQ(firmware_reset(&before, now), "");
}

TEST(LinkErrors, AreWordsNeverABareErrno) {
  for (int e : {ETIMEDOUT, ENODEV, EIO, ENOENT, ENOTCONN, EBUSY, EPROTO, EBADMSG, EOPNOTSUPP, EACCES}) {
    std::string text = link::error_text(-e);
    EXPECT_GT(text.size(), 10u) << e;
    EXPECT_EQ(text.find(std::to_string(e)), std::string::npos) << text;
  }
  EXPECT_EQ(link::failed("/dev/rbx1", "STATUS", -ETIMEDOUT),
            "/dev/rbx1: STATUS failed: no answer from the firmware after every retransmission (check the cable and "
            "the board's power)");
  EXPECT_NE(link::error_text(-EPROTO).find("rbx1-flash"), std::string::npos);  // what to do
  EXPECT_EQ(link::error_text(-EACCES), std::strerror(EACCES));
}

TEST(ErrorCodes, TheEnumAndTheWireNamesAreOneList) {
  const auto& all = error_codes();
  for (size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(size_t(all[i].id), i) << all[i].code;
    EXPECT_EQ(&error_info(all[i].id), &all[i]);
    EXPECT_EQ(find_error(all[i].code), &all[i]);
  }
  EXPECT_STREQ(code_name(ErrorCode::NotReady), "not_ready");
  EXPECT_STREQ(code_name(ErrorCode::FirmwareReset), "firmware_reset");
  EXPECT_STREQ(code_name(ErrorCode::TooManyStreams), "too_many_streams");
  Error e(ErrorCode::Busy, "a job is running (pick)");
  EXPECT_EQ(error_reply(e), nlohmann::json::parse(R"j({"error":{"code":"busy","message":"a job is running (pick)"}})j"));
  // The workspace fit's codes (host/calib) are in the list too: a reply never carries an unlisted code.
  EXPECT_NE(find_error("degenerate"), nullptr);
  EXPECT_NE(find_error("duplicate_marker"), nullptr);
}
