// daemon_test.cpp - request parsing, the control socket (framing, limits, error replies, mode) and [daemon] config.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <thread>

#include "control_client.hpp"
#include "daemon_config.hpp"
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
