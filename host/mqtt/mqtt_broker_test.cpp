// mqtt_broker_test.cpp - MqttInterface against a real mosquitto started here on a free loopback port, with a
// password file and an ACL (and a TLS listener with a CA made by openssl), driven by a Bus the test publishes to and
// a stand-in request handler that counts what it runs.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <pwd.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>
#include <mosquitto.h>
#include <mqtt_protocol.h>

#include "mqtt_interface.hpp"

using namespace rbx1;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

int free_port() {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  close(fd);
  return ntohs(a.sin_port);
}

bool port_open(int port) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(fd);
  return ok;
}

int run(const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()); }

// mosquitto with users arm1 (its prefix), viewer (reads only), controller (reads, writes commands), no anonymous.
class Broker {
 public:
  explicit Broker(bool tls) : dir_(fs::temp_directory_path() / ("rbx1-mqtt-" + std::to_string(getpid()) + "-" +
                                                                std::to_string(free_port()))) {
    fs::create_directories(dir_);
    port_ = free_port();
    std::string pw = (dir_ / "passwd").string();
    run("mosquitto_passwd -c -b " + pw + " arm1 arm1-secret");
    run("mosquitto_passwd -b " + pw + " viewer viewer-secret");
    run("mosquitto_passwd -b " + pw + " controller controller-secret");
    std::ofstream(dir_ / "arm1.pw") << "arm1-secret\n";
    std::ofstream(dir_ / "acl") << "user arm1\ntopic readwrite rbx1/arm1/#\ntopic readwrite homeassistant/#\n"
                                   "user viewer\ntopic read rbx1/#\ntopic read homeassistant/#\n"
                                   "user controller\ntopic read rbx1/#\ntopic write rbx1/+/cmd\n"
                                   "topic write rbx1/+/recipe/set\ntopic write rbx1/+/recipe/sort\n"
                                   "topic readwrite homeassistant/status\ntopic read homeassistant/#\n";
    std::ofstream conf(dir_ / "mosquitto.conf");
    // As root, mosquitto would drop to user "mosquitto", who cannot read this folder: stay who we are.
    conf << "user " << getpwuid(geteuid())->pw_name << "\n";
    conf << "per_listener_settings false\nallow_anonymous false\npassword_file " << pw << "\nacl_file "
         << (dir_ / "acl").string() << "\npersistence false\nlog_dest file " << (dir_ / "mosquitto.log").string()
         << "\nlistener " << port_ << " 127.0.0.1\n";
    if (tls) {
      tls_port_ = free_port();
      std::string d = dir_.string();
      // A CA and a server certificate for 127.0.0.1, made here: nothing from the machine's trust store.
      run("openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=rbx1-test-ca -keyout " + d + "/ca.key -out " +
          d + "/ca.pem");
      run("openssl req -newkey rsa:2048 -nodes -subj /CN=127.0.0.1 -keyout " + d + "/server.key -out " + d +
          "/server.csr");
      std::ofstream(dir_ / "san.ext") << "subjectAltName=IP:127.0.0.1,DNS:localhost\n";
      run("openssl x509 -req -in " + d + "/server.csr -CA " + d + "/ca.pem -CAkey " + d + "/ca.key -CAcreateserial -days 1 -extfile " +
          d + "/san.ext -out " + d + "/server.pem");
      conf << "listener " << tls_port_ << " 127.0.0.1\ncafile " << d << "/ca.pem\ncertfile " << d
           << "/server.pem\nkeyfile " << d << "/server.key\n";
    }
    conf.close();
    start();
  }
  ~Broker() {
    stop();
    fs::remove_all(dir_);
  }
  void start() {
    pid_ = fork();
    if (pid_ == 0) {
      execlp("mosquitto", "mosquitto", "-c", (dir_ / "mosquitto.conf").c_str(), nullptr);
      _exit(127);
    }
    for (int i = 0; i < 200 && !port_open(port_); ++i) std::this_thread::sleep_for(20ms);
  }
  void stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  int port() const { return port_; }
  int tls_port() const { return tls_port_; }
  fs::path dir() const { return dir_; }

 private:
  fs::path dir_;
  int port_ = 0, tls_port_ = 0;
  pid_t pid_ = -1;
};

struct Message {
  std::string topic, payload, correlation;
  bool retain = false;
};

// A plain MQTT 5 client of the broker (the dashboard, the cell controller, the viewer).
class Client {
 public:
  Client(int port, const char* user, const char* password, const std::string& id) {
    mosquitto_lib_init();
    m_ = mosquitto_new(id.c_str(), true, this);
    mosquitto_int_option(m_, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
    if (user) mosquitto_username_pw_set(m_, user, password);
    mosquitto_connect_v5_callback_set(m_, [](mosquitto*, void* self, int rc, int, const mosquitto_property*) {
      auto* c = static_cast<Client*>(self);
      std::lock_guard lock(c->mu_);
      c->connack_ = rc;
      c->cv_.notify_all();
    });
    mosquitto_subscribe_v5_callback_set(m_, [](mosquitto*, void* self, int, int, const int*, const mosquitto_property*) {
      auto* c = static_cast<Client*>(self);
      std::lock_guard lock(c->mu_);
      ++c->subacks_;
      c->cv_.notify_all();
    });
    mosquitto_message_v5_callback_set(m_, [](mosquitto*, void* self, const mosquitto_message* msg,
                                             const mosquitto_property* props) {
      auto* c = static_cast<Client*>(self);
      Message m{msg->topic, std::string(static_cast<const char*>(msg->payload), size_t(msg->payloadlen)), "", msg->retain};
      void* cd = nullptr;
      uint16_t n = 0;
      if (mosquitto_property_read_binary(props, MQTT_PROP_CORRELATION_DATA, &cd, &n, false)) {
        m.correlation.assign(static_cast<char*>(cd), n);
        free(cd);
      }
      std::lock_guard lock(c->mu_);
      c->messages_.push_back(std::move(m));
      c->cv_.notify_all();
    });
    mosquitto_connect(m_, "127.0.0.1", port, 10);
    mosquitto_loop_start(m_);
  }
  ~Client() {
    mosquitto_disconnect(m_);
    mosquitto_loop_stop(m_, false);
    mosquitto_destroy(m_);
  }
  // The CONNACK's reason code (0: accepted), -1 when none came.
  int connack(std::chrono::milliseconds timeout = 5s) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, timeout, [&] { return connack_ >= 0; });
    return connack_;
  }
  void subscribe(const std::string& topic) {
    std::unique_lock lock(mu_);
    int want = subacks_ + 1;
    lock.unlock();
    mosquitto_subscribe_v5(m_, nullptr, topic.c_str(), 1, 0, nullptr);
    lock.lock();
    cv_.wait_for(lock, 5s, [&] { return subacks_ >= want; });
  }
  void publish(const std::string& topic, const std::string& payload, bool retain = false,
               const std::string& response_topic = "", const std::string& correlation = "") {
    mosquitto_property* props = nullptr;
    if (!response_topic.empty()) mosquitto_property_add_string(&props, MQTT_PROP_RESPONSE_TOPIC, response_topic.c_str());
    if (!correlation.empty())
      mosquitto_property_add_binary(&props, MQTT_PROP_CORRELATION_DATA, correlation.data(), uint16_t(correlation.size()));
    mosquitto_publish_v5(m_, nullptr, topic.c_str(), int(payload.size()), payload.data(), 1, retain, props);
    mosquitto_property_free_all(&props);
  }
  // The first message (from index `from`) matching pred within timeout.
  std::optional<Message> wait(const std::function<bool(const Message&)>& pred, std::chrono::milliseconds timeout = 5s,
                              size_t* from = nullptr) {
    std::unique_lock lock(mu_);
    std::optional<Message> found;
    size_t start = from ? *from : 0;
    cv_.wait_for(lock, timeout, [&] {
      for (size_t i = start; i < messages_.size(); ++i)
        if (pred(messages_[i])) {
          found = messages_[i];
          if (from) *from = i + 1;
          return true;
        }
      return false;
    });
    return found;
  }
  std::optional<Message> wait_topic(const std::string& topic, std::chrono::milliseconds timeout = 5s) {
    return wait([&](const Message& m) { return m.topic == topic; }, timeout);
  }
  size_t count(const std::string& topic) {
    std::lock_guard lock(mu_);
    return size_t(std::count_if(messages_.begin(), messages_.end(), [&](const Message& m) { return m.topic == topic; }));
  }
  std::vector<Message> messages() {
    std::lock_guard lock(mu_);
    return messages_;
  }
  void clear() {
    std::lock_guard lock(mu_);
    messages_.clear();
  }

 private:
  mosquitto* m_;
  std::mutex mu_;
  std::condition_variable cv_;
  int connack_ = -1, subacks_ = 0;
  std::vector<Message> messages_;
};

// Stands in for Machine::handle: status at once, estop at once, home a 300 ms job; counts what ran and keeps the
// last request of each command.
class FakeArm {
 public:
  ~FakeArm() {
    for (auto& t : jobs_) t.join();
  }
  daemon::Handler handler() {
    return [this](const daemon::Request& r, std::shared_ptr<daemon::Reply> reply) {
      std::lock_guard lock(mu_);
      ++runs_[daemon::command_name(r.command)];
      last_[daemon::command_name(r.command)] = r;
      if (r.command == daemon::Command::Home) {
        jobs_.emplace_back([reply] {
          std::this_thread::sleep_for(300ms);
          reply->event("homing");
          reply->result({{"homed", true}});
        });
        return;
      }
      reply->result({{"cmd", daemon::command_name(r.command)}});
    };
  }
  int runs(const std::string& cmd) {
    std::lock_guard lock(mu_);
    return runs_[cmd];
  }
  daemon::Request last(const std::string& cmd) {
    std::lock_guard lock(mu_);
    return last_[cmd];
  }

 private:
  std::mutex mu_;
  std::map<std::string, int> runs_;
  std::map<std::string, daemon::Request> last_;
  std::vector<std::thread> jobs_;
};

mqtt::MqttConfig arm_config(const Broker& b) {
  mqtt::MqttConfig c;
  c.enabled = true;
  c.host = "127.0.0.1";
  c.port = b.port();
  c.client_id = "arm1";
  c.username = "arm1";
  c.password_file = (b.dir() / "arm1.pw").string();
  c.prefix = "rbx1/arm1";
  c.keepalive_s = 5;
  c.state_rate_hz = 5;
  return c;
}

bool eventually(const std::function<bool()>& f, std::chrono::milliseconds timeout = 5s) {
  auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (f()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return f();
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

struct MqttCell : ::testing::Test {
  Broker broker{false};
  FakeArm arm;
  daemon::Bus bus;
  std::unique_ptr<mqtt::MqttInterface> iface;
  void start(mqtt::MqttConfig c, const std::string& state_dir = "") {
    iface = std::make_unique<mqtt::MqttInterface>(c, "arm1", bus, arm.handler(), state_dir);
    std::string error;
    ASSERT_EQ(iface->start(error), 0) << error;
    ASSERT_TRUE(eventually([&] { return iface->connected(); })) << "the interface never connected";
    std::this_thread::sleep_for(2100ms);  // past the reconnect grace: commands without ts are taken
  }
  void start() { start(arm_config(broker)); }
  void TearDown() override {
    if (iface) iface->stop();
  }
};

}  // namespace

TEST_F(MqttCell, SecurityAnonymousRefusedViewerReadsOnlyArmStaysUnderItsPrefix) {
  start();
  Client anonymous(broker.port(), nullptr, nullptr, "anon");
  EXPECT_NE(anonymous.connack(), 0);
  Client wrong(broker.port(), "viewer", "guess", "wrong");
  EXPECT_NE(wrong.connack(), 0);

  Client viewer(broker.port(), "viewer", "viewer-secret", "viewer");
  ASSERT_EQ(viewer.connack(), 0);
  viewer.subscribe("rbx1/#");
  auto status = viewer.wait_topic("rbx1/arm1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->payload, "online");
  EXPECT_TRUE(status->retain);
  ASSERT_TRUE(viewer.wait_topic("rbx1/arm1/state"));  // the viewer sees the state...
  viewer.publish("rbx1/arm1/cmd", R"({"cmd":"home"})");  // ...but its command never reaches the arm
  Client controller(broker.port(), "controller", "controller-secret", "controller");
  ASSERT_EQ(controller.connack(), 0);
  controller.publish("rbx1/arm1/cmd", R"({"cmd":"status","id":"c1"})");
  ASSERT_TRUE(viewer.wait_topic("rbx1/arm1/cmd/response"));
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(arm.runs("home"), 0);
  EXPECT_EQ(arm.runs("status"), 1);

  // The arm's own user cannot write beside its prefix (another arm's command topic).
  Client arm1(broker.port(), "arm1", "arm1-secret", "arm1-other");
  ASSERT_EQ(arm1.connack(), 0);
  arm1.publish("rbx1/arm2/cmd", R"({"cmd":"home"})");
  arm1.publish("rbx1/arm1/probe", "mine");
  ASSERT_TRUE(viewer.wait_topic("rbx1/arm1/probe"));
  EXPECT_EQ(viewer.count("rbx1/arm2/cmd"), 0u);
}

TEST_F(MqttCell, RepliesOnResponseTopicOrCmdResponseWithId) {
  start();
  Client c(broker.port(), "arm1", "arm1-secret", "dash");  // may read and write under rbx1/arm1
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/#");
  c.publish("rbx1/arm1/cmd", R"({"cmd":"status"})", false, "rbx1/arm1/reply/dash", "corr-7");
  auto r = c.wait_topic("rbx1/arm1/reply/dash");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->correlation, "corr-7");
  EXPECT_EQ(json::parse(r->payload)["result"]["cmd"], "status");

  c.publish("rbx1/arm1/cmd", json{{"cmd", "home"}, {"id", "h-1"}, {"ts", now_s()}}.dump());
  auto h = c.wait([](const Message& m) { return m.topic == "rbx1/arm1/cmd/response" && m.payload.find("h-1") != std::string::npos; });
  ASSERT_TRUE(h);
  EXPECT_EQ(json::parse(h->payload), (json{{"id", "h-1"}, {"result", {{"homed", true}}}}));
}

TEST_F(MqttCell, AtMostOncePerIdAndStaleCommandsRefused) {
  start();
  Client c(broker.port(), "controller", "controller-secret", "ctl");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/cmd/response");
  std::string home = json{{"cmd", "home"}, {"id", "once"}, {"ts", now_s()}}.dump();
  c.publish("rbx1/arm1/cmd", home);
  c.publish("rbx1/arm1/cmd", home);  // while the first still runs
  ASSERT_TRUE(eventually([&] { return c.count("rbx1/arm1/cmd/response") == 2; }));
  c.publish("rbx1/arm1/cmd", home);  // after it ended
  ASSERT_TRUE(eventually([&] { return c.count("rbx1/arm1/cmd/response") == 3; }));
  auto all = c.messages();
  EXPECT_EQ(arm.runs("home"), 1);
  for (const auto& m : all) EXPECT_EQ(json::parse(m.payload)["result"]["homed"], true) << m.payload;

  c.clear();
  c.publish("rbx1/arm1/cmd", json{{"cmd", "home"}, {"id", "old"}, {"ts", now_s() - 600}}.dump());
  auto stale = c.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(stale);
  EXPECT_EQ(json::parse(stale->payload)["error"]["code"], "stale");
  EXPECT_EQ(arm.runs("home"), 1);
  // A stop is never stale: an old one still stops.
  c.publish("rbx1/arm1/cmd", json{{"cmd", "estop"}, {"ts", now_s() - 600}}.dump());
  ASSERT_TRUE(eventually([&] { return arm.runs("estop") == 1; }));
}

TEST_F(MqttCell, GarbageGetsAnErrorReplyAndNeverStalls) {
  start();
  Client c(broker.port(), "controller", "controller-secret", "ctl");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/cmd/response");
  std::vector<std::pair<std::string, std::string>> cases{
      {"not json", "bad_json"},
      {std::string(1 << 20, 'x'), "too_large"},
      {R"({"cmd":"pick","name":7,"place":"tray","id":"g3"})", "bad_field"},
      {R"({"cmd":"dance","id":"g4"})", "unknown_command"},
      {R"({"cmd":"home","id":[1]})", "bad_field"},
      {R"({"cmd":"shutdown","id":"g6"})", "not_allowed"},
  };
  for (const auto& [payload, code] : cases) {
    size_t from = 0;
    c.clear();
    auto t0 = std::chrono::steady_clock::now();
    c.publish("rbx1/arm1/cmd", payload);
    auto r = c.wait_topic("rbx1/arm1/cmd/response");
    ASSERT_TRUE(r) << payload.substr(0, 40);
    EXPECT_EQ(json::parse(r->payload)["error"]["code"], code) << payload.substr(0, 40);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 2s);
    (void)from;
  }
  EXPECT_EQ(arm.runs("pick") + arm.runs("shutdown"), 0);
  c.clear();
  c.publish("rbx1/arm1/cmd", R"({"cmd":"status","id":"after"})");
  auto ok = c.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(ok);
  EXPECT_EQ(json::parse(ok->payload)["id"], "after");
}

TEST_F(MqttCell, StateRetainedOnChangeAtMostStateRate) {
  start();
  Client c(broker.port(), "viewer", "viewer-secret", "viewer");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/#");
  ASSERT_TRUE(c.wait_topic("rbx1/arm1/state"));
  c.clear();
  // 100 different statuses in about a second at state_rate_hz 5: at most ~6 state messages, the last one current.
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 100; ++i) {
    bus.publish(daemon::Topic::Status, {{"ready", true}, {"job", "pick"}, {"joints_deg", {i, 0, 0, 0, 0, 0}}});
    std::this_thread::sleep_for(10ms);
  }
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(eventually([&] {
    auto m = c.messages();
    return !m.empty() && json::parse(m.back().payload)["joints_deg"][0] == 99;
  }));
  size_t n = c.count("rbx1/arm1/state");
  EXPECT_LE(double(n), secs * 5 + 2);
  EXPECT_GE(n, 3u);
  // The same status again changes nothing: no message.
  c.clear();
  bus.publish(daemon::Topic::Status, {{"ready", true}, {"job", "pick"}, {"joints_deg", {99, 0, 0, 0, 0, 0}}});
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(c.count("rbx1/arm1/state"), 0u);
  // Events, scans and the history's pick rows go to their topics (the pick message is the row, nothing added); a
  // late subscriber gets the retained state at once.
  bus.publish(daemon::Topic::Events, {{"req", 5}, {"cmd", "sort"}, {"event", "chosen"}});
  bus.publish(daemon::Topic::Scans, {{"detections", {{"objects", json::array()}}}});
  json row{{"id", 3}, {"job", 1}, {"ts", "2026-12-02T09:00:00.000Z"}, {"class", "bolt"}, {"match_score", 0.93},
           {"grip_opening_cm", 1.2}, {"grip_angle_deg", 30.0}, {"place", "tray"}, {"phases_ms", {{"move", 8200}}},
           {"cycle_ms", 9100.5}, {"outcome", "picked"}, {"reason", ""}, {"attempt", 1}, {"scan", 4}, {"image", true}};
  bus.publish(daemon::Topic::Picks, row);
  EXPECT_TRUE(c.wait_topic("rbx1/arm1/event"));
  EXPECT_TRUE(c.wait_topic("rbx1/arm1/scan"));
  auto pick = c.wait_topic("rbx1/arm1/pick");
  ASSERT_TRUE(pick);
  EXPECT_EQ(json::parse(pick->payload), row);
  EXPECT_EQ(c.count("rbx1/arm1/pick"), 1u);
  Client late(broker.port(), "viewer", "viewer-secret", "late");
  ASSERT_EQ(late.connack(), 0);
  late.subscribe("rbx1/arm1/state");
  auto s = late.wait_topic("rbx1/arm1/state");
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->retain);
  ASSERT_TRUE(eventually([&] { return json::parse(late.messages().back().payload)["picks_today"] == 1; }));
}

TEST_F(MqttCell, BrokerRestartReconnectsAndRepublishes) {
  start();
  bus.publish(daemon::Topic::Status, {{"ready", true}, {"job", nullptr}});
  broker.stop();
  ASSERT_TRUE(eventually([&] { return !iface->connected(); }));
  // Events while the broker is away are dropped and counted, never queued.
  for (int i = 0; i < 50; ++i) bus.publish(daemon::Topic::Events, {{"req", 1}, {"event", "tick"}});
  ASSERT_TRUE(eventually([&] { return iface->counters().dropped >= 50; }));
  broker.start();  // persistence false: a broker that forgot every retained message
  ASSERT_TRUE(eventually([&] { return iface->connected(); }, 10s));
  EXPECT_EQ(iface->counters().connects, 2u);
  Client c(broker.port(), "viewer", "viewer-secret", "viewer");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/#");
  auto status = c.wait_topic("rbx1/arm1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->payload, "online");
  auto state = c.wait_topic("rbx1/arm1/state");
  ASSERT_TRUE(state);
  EXPECT_EQ(json::parse(state->payload)["mode"], "ready");
}

TEST_F(MqttCell, CommandWithoutTsRightAfterReconnectIsStale) {
  auto cfg = arm_config(broker);
  iface = std::make_unique<mqtt::MqttInterface>(cfg, "arm1", bus, arm.handler());
  Client c(broker.port(), "controller", "controller-secret", "ctl");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/cmd/response");
  std::string error;
  ASSERT_EQ(iface->start(error), 0) << error;
  ASSERT_TRUE(eventually([&] { return iface->connected(); }));
  std::this_thread::sleep_for(300ms);  // its subscription is in place; still within the 2 s after the connect
  c.publish("rbx1/arm1/cmd", R"({"cmd":"home","id":"queued"})");
  auto r = c.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(r);
  EXPECT_EQ(json::parse(r->payload)["error"]["code"], "stale");
  c.clear();
  c.publish("rbx1/arm1/cmd", json{{"cmd", "home"}, {"id", "fresh"}, {"ts", now_s()}}.dump());  // with ts: taken
  r = c.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(r);
  EXPECT_EQ(json::parse(r->payload)["result"]["homed"], true);
}

TEST_F(MqttCell, HomeAssistantDiscoveryRetainedAndRepublished) {
  auto cfg = arm_config(broker);
  cfg.homeassistant = true;
  start(cfg);
  Client ha(broker.port(), "controller", "controller-secret", "homeassistant");
  ASSERT_EQ(ha.connack(), 0);
  ha.subscribe("homeassistant/#");
  ASSERT_TRUE(eventually([&] { return ha.messages().size() >= 8; }));  // no recipes: no select, no Sort
  for (const auto& m : ha.messages()) EXPECT_TRUE(m.retain) << m.topic;
  ha.clear();
  ha.publish("homeassistant/status", "online");
  ASSERT_TRUE(eventually([&] { return ha.count("homeassistant/button/arm1/stop/config") == 1; }));
}

// The recipe select: its options are recipes.json's names (republished when the file changes); choosing only
// remembers (nothing runs); Sort runs a sort with the chosen recipe; after a restart the broker's retained choice
// is taken back.
TEST_F(MqttCell, HomeAssistantRecipeSelectChoosesAndSortStartsIt) {
  fs::path state = broker.dir() / "state";
  fs::create_directories(state);
  auto save_recipes = [&](const json& recipes) {  // as RecipeBook::save does: a new file renamed over the old
    std::ofstream(state / "recipes.json.tmp") << recipes.dump();
    fs::rename(state / "recipes.json.tmp", state / "recipes.json");
  };
  save_recipes({{"bolts", {{"bolt", "tray"}}}, {"mixed", {{"*", "bin"}, {"unknown", "bin"}}}});
  auto cfg = arm_config(broker);
  cfg.homeassistant = true;
  start(cfg, state.string());
  Client ha(broker.port(), "controller", "controller-secret", "homeassistant");
  ASSERT_EQ(ha.connack(), 0);
  ha.subscribe("homeassistant/#");
  ha.subscribe("rbx1/arm1/#");
  const std::string select_topic = "homeassistant/select/arm1/recipe/config";
  auto select = ha.wait_topic(select_topic);
  ASSERT_TRUE(select);
  EXPECT_TRUE(select->retain);
  json device{{"identifiers", {"rbx1_arm1"}}, {"name", "RBX1 arm1"}, {"manufacturer", "RBX1 project"},
              {"model", "RBX1 arm (rbx1d)"}};
  json common{{"device", device}, {"availability_topic", "rbx1/arm1/status"}, {"payload_available", "online"},
              {"payload_not_available", "offline"}};
  json want_select = common;
  want_select.update({{"name", "Recipe (chooses only; Sort starts it)"}, {"unique_id", "rbx1_arm1_recipe"},
                      {"object_id", "rbx1_arm1_recipe"}, {"icon", "mdi:clipboard-list"},
                      {"command_topic", "rbx1/arm1/recipe/set"}, {"state_topic", "rbx1/arm1/recipe"},
                      {"options", {"bolts", "mixed"}}, {"qos", 1}});
  EXPECT_EQ(json::parse(select->payload), want_select);
  auto sort_button = ha.wait_topic("homeassistant/button/arm1/sort/config");
  ASSERT_TRUE(sort_button);
  json want_sort = common;
  want_sort.update({{"name", "Sort (the chosen recipe)"}, {"unique_id", "rbx1_arm1_sort"},
                    {"object_id", "rbx1_arm1_sort"}, {"icon", "mdi:sort"}, {"command_topic", "rbx1/arm1/recipe/sort"},
                    {"payload_press", "PRESS"}, {"qos", 1}});
  EXPECT_EQ(json::parse(sort_button->payload), want_sort);

  // A recipe saved: the select's options follow recipes.json's names.
  save_recipes({{"bolts", {{"bolt", "tray"}}}, {"mixed", {{"*", "bin"}}}, {"nuts", {{"nut", "bin"}}}});
  auto republished = ha.wait([&](const Message& m) {
    return m.topic == select_topic && m.payload.find("nuts") != std::string::npos;
  });
  ASSERT_TRUE(republished) << "the select was not republished after recipes.json changed";
  json names = json::array();
  std::ifstream file(state / "recipes.json");
  json saved = json::parse(file);
  for (const auto& [name, recipe] : saved.items()) names.push_back(name);
  EXPECT_EQ(json::parse(republished->payload)["options"], names);

  // Sort with nothing chosen: refused, nothing runs.
  ha.publish("rbx1/arm1/recipe/sort", "PRESS");
  auto refused = ha.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(refused);
  EXPECT_EQ(json::parse(refused->payload)["error"]["code"], "unknown_recipe");
  // Choosing moves nothing: the choice is shown (retained), no request runs.
  auto on_recipe = [](const Message& m) { return m.topic == "rbx1/arm1/recipe"; };
  size_t at = 0;
  ha.publish("rbx1/arm1/recipe/set", "nuts");
  auto chosen = ha.wait(on_recipe, 5s, &at);
  ASSERT_TRUE(chosen);
  EXPECT_EQ(chosen->payload, "nuts");
  ha.publish("rbx1/arm1/recipe/set", "no-such-recipe");  // refused: the select shows the choice it had
  auto kept = ha.wait(on_recipe, 5s, &at);
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->payload, "nuts");
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(arm.runs("sort"), 0);
  // Sort starts a sort with the chosen recipe, through the same rules as a request on cmd.
  ha.clear();
  ha.publish("rbx1/arm1/recipe/sort", "PRESS");
  auto started = ha.wait_topic("rbx1/arm1/cmd/response");
  ASSERT_TRUE(started);
  EXPECT_EQ(json::parse(started->payload)["result"]["cmd"], "sort");
  EXPECT_EQ(arm.runs("sort"), 1);
  EXPECT_EQ(arm.last("sort").recipe, "nuts");

  // A restart: the choice retained on the broker is taken back; Sort runs it again.
  iface->stop();
  start(cfg, state.string());
  ha.clear();
  ha.publish("rbx1/arm1/recipe/sort", "PRESS");
  ASSERT_TRUE(ha.wait_topic("rbx1/arm1/cmd/response"));
  EXPECT_EQ(arm.runs("sort"), 2);
  EXPECT_EQ(arm.last("sort").recipe, "nuts");

  // The chosen recipe gone from recipes.json: nothing is chosen (its retained choice removed); no recipe left:
  // the select and the Sort button are removed (empty retained configs).
  ha.clear();
  save_recipes({{"bolts", {{"bolt", "tray"}}}});
  ASSERT_TRUE(ha.wait([](const Message& m) { return m.topic == "rbx1/arm1/recipe" && m.payload.empty(); }));
  save_recipes(json::object());
  ASSERT_TRUE(ha.wait([&](const Message& m) { return m.topic == select_topic && m.payload.empty(); }));
  ASSERT_TRUE(ha.wait([](const Message& m) { return m.topic == "homeassistant/button/arm1/sort/config" && m.payload.empty(); }));
}

TEST(MqttTls, ConnectsWithTheTestCa) {
  Broker broker(true);
  FakeArm arm;
  daemon::Bus bus;
  auto cfg = arm_config(broker);
  cfg.port = broker.tls_port();
  cfg.ca_file = (broker.dir() / "ca.pem").string();
  mqtt::MqttInterface iface(cfg, "arm1", bus, arm.handler());
  std::string error;
  ASSERT_EQ(iface.start(error), 0) << error;
  ASSERT_TRUE(eventually([&] { return iface.connected(); }, 10s)) << "no TLS connection to 127.0.0.1:" << cfg.port;
  Client c(broker.port(), "viewer", "viewer-secret", "viewer");  // the plain listener of the same broker
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/status");
  auto s = c.wait_topic("rbx1/arm1/status");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->payload, "online");
  iface.stop();
  auto off = c.wait([](const Message& m) { return m.payload == "offline"; });
  EXPECT_TRUE(off) << "stop() must leave offline (retained) behind";
}

// A broker that is not there yet never holds up the daemon's start; the interface connects once it comes.
TEST_F(MqttCell, StartsWithoutTheBrokerAndConnectsWhenItComes) {
  broker.stop();
  iface = std::make_unique<mqtt::MqttInterface>(arm_config(broker), "arm1", bus, arm.handler());
  std::string error;
  auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(iface->start(error), 0) << error;
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 500ms);
  std::this_thread::sleep_for(1500ms);
  EXPECT_FALSE(iface->connected());
  broker.start();
  ASSERT_TRUE(eventually([&] { return iface->connected(); }, 15s));
  Client c(broker.port(), "viewer", "viewer-secret", "viewer");
  ASSERT_EQ(c.connack(), 0);
  c.subscribe("rbx1/arm1/status");
  auto s = c.wait_topic("rbx1/arm1/status");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->payload, "online");
}
