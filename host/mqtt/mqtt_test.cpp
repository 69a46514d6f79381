// mqtt_test.cpp - the MQTT interface's pure parts: [mqtt] config, the command decoder (cases and a randomized
// run), the at-most-once cache, the state document, Home Assistant discovery.
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "command_decode.hpp"
#include "ha_discovery.hpp"
#include "mqtt_config.hpp"
#include "replay_cache.hpp"
#include "state_view.hpp"

using namespace rbx1;
using nlohmann::json;

namespace {
mqtt::MqttConfig parse(const std::string& text, config::Errors& errors, const std::string& arm = "arm1") {
  toml::table root = config::parse_text(text, errors);
  config::Section top(&root, "", errors);
  mqtt::MqttConfig c;
  mqtt::parse_mqtt_config(top.section("mqtt"), arm, c);
  return c;
}
}  // namespace

TEST(MqttConfig, DefaultsFollowArmId) {
  config::Errors e;
  auto c = parse("", e, "cell-a");
  ASSERT_TRUE(e.ok()) << e.joined();
  EXPECT_FALSE(c.enabled);
  EXPECT_EQ(c.prefix, "rbx1/cell-a");
  EXPECT_EQ(c.client_id, "cell-a");
  EXPECT_EQ(c.port, 1883);
  auto tls = parse("[mqtt]\nca_file = \"/etc/ssl/ca.pem\"\n", e);
  EXPECT_EQ(tls.port, 8883);
}

// The keepalive sent to the broker: within 1.5 x keepalive_s despite mosquitto 2.0's 6 s check, where that can be.
TEST(MqttConfig, BrokerKeepaliveFitsTheBrokersCheck) {
  EXPECT_EQ(mqtt::broker_keepalive_s(5), 5);    // cannot: 5 is libmosquitto's least
  EXPECT_EQ(mqtt::broker_keepalive_s(9), 5);
  EXPECT_EQ(mqtt::broker_keepalive_s(10), 5);   // 7 + 7 <= 15
  EXPECT_EQ(mqtt::broker_keepalive_s(20), 15);  // 22 + 7 <= 30
  EXPECT_EQ(mqtt::broker_keepalive_s(60), 55);
  EXPECT_EQ(mqtt::broker_keepalive_s(3600), 3595);
}

TEST(MqttConfig, ErrorsNameTheirKey) {
  struct Case {
    const char* text;
    const char* key;
  } cases[] = {
      {"[mqtt]\nport = 0\n", "mqtt.port"},
      {"[mqtt]\nprefix = \"rbx1/#\"\n", "mqtt.prefix"},
      {"[mqtt]\nprefix = \"/rbx1\"\n", "mqtt.prefix"},
      {"[mqtt]\nstate_rate_hz = 1000\n", "mqtt.state_rate_hz"},
      {"[mqtt]\nkeepalive_s = 1\n", "mqtt.keepalive_s"},
      {"[mqtt]\npassword = \"secret\"\nusername = \"u\"\n", "mqtt.password"},
      {"[mqtt]\npassword_file = \"/x\"\n", "mqtt.username"},
      {"[mqtt]\ncert_file = \"c.pem\"\n", "mqtt.key_file"},
      {"[mqtt]\ncert_file = \"c.pem\"\nkey_file = \"k.pem\"\n", "mqtt.ca_file"},
      {"[mqtt]\nhomeassistant = 1\n", "mqtt.homeassistant"},
      {"[mqtt]\nbroker = \"x\"\n", "mqtt.broker"},
  };
  for (const auto& c : cases) {
    config::Errors e;
    parse(c.text, e);
    ASSERT_FALSE(e.ok()) << c.text;
    EXPECT_EQ(e.messages()[0].rfind(std::string(c.key) + ":", 0), 0u) << c.text << " -> " << e.joined();
  }
}

TEST(CommandDecode, EnvelopeIsTakenOff) {
  mqtt::Incoming in;
  daemon::Error err;
  ASSERT_TRUE(mqtt::decode_command(R"({"cmd":"pick","name":"bolt","place":"tray","id":"j-1","ts":1790000000.5})", in, err));
  EXPECT_EQ(in.id, "j-1");
  EXPECT_DOUBLE_EQ(*in.ts, 1790000000.5);
  EXPECT_EQ(in.cmd, "pick");
  daemon::Request r;
  ASSERT_TRUE(daemon::parse_request(in.line, r, err)) << err.message;  // no id or ts left for the strict parser
  EXPECT_EQ(r.name, "bolt");
  ASSERT_TRUE(mqtt::decode_command(R"({"cmd":"home","ts":"2026-11-22T01:02:03.250Z","id":42})", in, err));
  EXPECT_EQ(in.id, 42);
  EXPECT_DOUBLE_EQ(*in.ts, 1795309323.25);
  EXPECT_EQ(mqtt::with_id(R"({"result":{"ok":true}})", in.id), R"({"id":42,"result":{"ok":true}})");
}

TEST(CommandDecode, GarbageIsAnErrorValue) {
  struct Case {
    std::string payload;
    const char* code;
  } cases[] = {
      {std::string(1 << 20, '{'), "too_large"},
      {"not json", "bad_json"},
      {"", "bad_json"},
      {"[1,2]", "bad_request"},
      {R"({"cmd":"home","id":{}})", "bad_field"},
      {R"({"cmd":"home","id":""})", "bad_field"},
      {R"({"cmd":"home","ts":"yesterday"})", "bad_field"},
      {R"({"cmd":"home","ts":true})", "bad_field"},
  };
  for (const auto& c : cases) {
    mqtt::Incoming in;
    daemon::Error err;
    EXPECT_FALSE(mqtt::decode_command(c.payload, in, err)) << c.payload.substr(0, 40);
    EXPECT_EQ(err.code, c.code) << c.payload.substr(0, 40);
  }
}

TEST(CommandDecode, StaleRule) {
  mqtt::Incoming in;
  daemon::Error err;
  ASSERT_TRUE(mqtt::decode_command(R"({"cmd":"home"})", in, err));
  EXPECT_EQ(mqtt::stale_reason(in, false, 1000, 30, false), "");
  EXPECT_NE(mqtt::stale_reason(in, false, 1000, 30, true), "");  // just reconnected and no ts: cannot tell
  EXPECT_NE(mqtt::stale_reason(in, true, 1000, 30, false), "");  // retained
  in.ts = 1000 - 31;
  EXPECT_NE(mqtt::stale_reason(in, false, 1000, 30, false), "");
  in.ts = 1000 - 29;
  EXPECT_EQ(mqtt::stale_reason(in, false, 1000, 30, true), "");  // a fresh ts counts even right after a reconnect
  in.ts = 1000 + 60;
  EXPECT_NE(mqtt::stale_reason(in, false, 1000, 30, false), "");
  in.ts = 1.7e101;  // found by the fuzzer: the age once went through a conversion to long (undefined behaviour)
  EXPECT_EQ(mqtt::stale_reason(in, false, 1000, 30, false).rfind("\"ts\" is 1", 0), 0u);
}

// Randomized: mutations of valid commands and random bytes never throw, and end as a request or a known error.
TEST(CommandDecode, RandomizedNeverThrows) {
  const std::set<std::string> codes{"too_large", "bad_json",      "bad_request",   "bad_field",
                                    "missing_field", "unknown_command", "line_too_long"};
  const std::vector<std::string> seeds{R"({"cmd":"pick","name":"bolt","place":"tray","id":"a","ts":1790000000})",
                                       R"({"cmd":"jog","joint":1,"deg":2.5,"id":3})", R"({"cmd":"estop"})",
                                       R"({"cmd":"calibrate_workspace","action":"record","index":4})"};
  std::mt19937 rng(20261202);
  const std::string alphabet = "{}[]\":,0123456789.eE+-truefalsnl \\u00ff\x01\x7f";
  int requests = 0, errors = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string p = seeds[rng() % seeds.size()];
    int edits = 1 + int(rng() % 6);
    for (int k = 0; k < edits; ++k) {
      size_t at = p.empty() ? 0 : rng() % p.size();
      switch (rng() % 4) {
        case 0: if (!p.empty()) p.erase(at, 1 + rng() % 3); break;
        case 1: p.insert(at, 1, alphabet[rng() % alphabet.size()]); break;
        case 2: if (!p.empty()) p[at] = char(rng()); break;
        default: p.insert(at, p.substr(0, rng() % (p.size() + 1))); break;
      }
    }
    if (i % 1000 == 0) p.assign(rng() % 9000, char(rng()));
    mqtt::Incoming in;
    daemon::Error err;
    daemon::Request r;
    bool ok = false;
    ASSERT_NO_THROW(ok = mqtt::decode_command(p, in, err) && daemon::parse_request(in.line, r, err)) << p;
    if (ok) ++requests;
    else {
      ++errors;
      ASSERT_TRUE(codes.count(err.code)) << err.code << " for " << p;
    }
  }
  EXPECT_GT(requests, 100);  // the mutations reach the request parser, not only the JSON one
  EXPECT_GT(errors, 1000);
}

TEST(ReplayCache, FirstReplyAnswersRepeatsUntilTtl) {
  mqtt::ReplayCache c(600, 100);
  std::string reply;
  EXPECT_EQ(c.check("\"a\"", 0, reply, nullptr), mqtt::ReplayCache::Seen::New);
  std::vector<std::string> waited;
  EXPECT_EQ(c.check("\"a\"", 1, reply, [&](const std::string& l) { waited.push_back(l); }),
            mqtt::ReplayCache::Seen::Pending);
  c.finish("\"a\"", "first");
  ASSERT_EQ(waited, std::vector<std::string>{"first"});
  EXPECT_EQ(c.check("\"a\"", 599, reply, nullptr), mqtt::ReplayCache::Seen::Done);
  EXPECT_EQ(reply, "first");
  EXPECT_EQ(c.check("\"a\"", 601, reply, nullptr), mqtt::ReplayCache::Seen::New);  // ten minutes later: new
}

TEST(ReplayCache, BoundedAndKeepsRunningOnes) {
  mqtt::ReplayCache c(600, 10);
  std::string reply;
  c.check("running", 0, reply, nullptr);  // never finished: must never run twice
  for (int i = 0; i < 50; ++i) {
    c.check(std::to_string(i), i, reply, nullptr);
    c.finish(std::to_string(i), "r");
  }
  EXPECT_LE(c.size(), 11u);
  EXPECT_EQ(c.check("running", 51, reply, nullptr), mqtt::ReplayCache::Seen::Pending);
}

TEST(StateView, ModeProgressAndPicks) {
  mqtt::StateView v("arm1");
  v.on_status({{"ready", true}, {"job", nullptr}, {"firmware", {{"state", "IDLE"}}}, {"seq", 1}, {"topic", "status"}});
  EXPECT_EQ(v.document()["mode"], "ready");
  EXPECT_FALSE(v.document().contains("seq"));
  EXPECT_TRUE(v.changed());
  v.take();
  EXPECT_FALSE(v.changed());
  v.on_status({{"ready", true}, {"job", nullptr}, {"firmware", {{"state", "IDLE"}}}, {"seq", 2}, {"topic", "status"}});
  EXPECT_FALSE(v.changed());  // only seq differs
  v.on_event({{"req", 3}, {"cmd", "pick"}, {"event", "grasp"}}, 0);
  EXPECT_EQ(v.document()["progress"]["event"], "grasp");
  v.on_event({{"req", 3}, {"cmd", "pick"}, {"final", true}, {"result", {{"placed", true}}}}, 0);
  EXPECT_EQ(v.document()["picks_today"], 1);  // a single pick (not in the history)
  EXPECT_TRUE(v.document()["progress"].is_null());
  // A sort's history rows: the pick message is the row itself; only "picked" counts.
  json row{{"id", 7}, {"job", 2}, {"class", "bolt"}, {"outcome", "picked"}, {"reason", ""}};
  json bus_row = row;
  bus_row["topic"] = "picks";
  bus_row["seq"] = 41;
  EXPECT_EQ(v.on_pick_row(bus_row, 0), row);
  bus_row["outcome"] = "failed";
  v.on_pick_row(bus_row, 0);
  EXPECT_EQ(v.document()["picks_today"], 2);
  v.on_status({{"ready", false}, {"job", nullptr}, {"firmware", {{"state", "FAULT"}, {"faults", {"ESTOP_COMMAND"}}}}});
  EXPECT_EQ(v.document()["mode"], "estop");
  v.on_status({{"ready", false}, {"job", nullptr}, {"firmware", {{"state", "FAULT"}, {"faults", {"LIMIT_HIT"}}}}});
  EXPECT_EQ(v.document()["mode"], "fault");
}

TEST(HaDiscovery, OneDeviceWithAvailability) {
  auto configs = mqtt::discovery_configs("arm 1", "rbx1/arm 1", {"bolts"});
  ASSERT_EQ(configs.size(), 10u);
  std::set<std::string> ids;
  for (const auto& [topic, payload] : configs) {
    EXPECT_EQ(topic.rfind("homeassistant/", 0), 0u);
    EXPECT_EQ(topic.find(' '), std::string::npos) << topic;  // node ids are sanitized
    json c = json::parse(payload);
    EXPECT_EQ(c["availability_topic"], "rbx1/arm 1/status");
    EXPECT_EQ(c["device"]["identifiers"][0], "rbx1_arm_1");
    ids.insert(c["unique_id"].get<std::string>());
  }
  EXPECT_EQ(ids.size(), configs.size());
  EXPECT_NE(configs[6].second.find(R"({\"cmd\":\"estop\"})"), std::string::npos);
}

// The recipes: a select that only chooses (its command topic is not cmd) and a Sort button that starts the chosen
// one; both removed (empty retained configs) while no recipe is saved.
TEST(HaDiscovery, RecipeSelectAndSortButton) {
  json device{{"identifiers", {"rbx1_arm1"}}, {"name", "RBX1 arm1"}, {"manufacturer", "RBX1 project"},
              {"model", "RBX1 arm (rbx1d)"}};
  auto with = mqtt::discovery_configs("arm1", "rbx1/arm1", {"bolts", "mixed"});
  ASSERT_EQ(with.size(), 10u);
  EXPECT_EQ(with[8].first, "homeassistant/select/arm1/recipe/config");
  EXPECT_EQ(json::parse(with[8].second),
            (json{{"name", "Recipe (chooses only; Sort starts it)"}, {"unique_id", "rbx1_arm1_recipe"},
                  {"object_id", "rbx1_arm1_recipe"}, {"device", device}, {"availability_topic", "rbx1/arm1/status"},
                  {"payload_available", "online"}, {"payload_not_available", "offline"},
                  {"icon", "mdi:clipboard-list"}, {"command_topic", "rbx1/arm1/recipe/set"},
                  {"state_topic", "rbx1/arm1/recipe"}, {"options", {"bolts", "mixed"}}, {"qos", 1}}));
  EXPECT_EQ(with[9].first, "homeassistant/button/arm1/sort/config");
  EXPECT_EQ(json::parse(with[9].second),
            (json{{"name", "Sort (the chosen recipe)"}, {"unique_id", "rbx1_arm1_sort"}, {"object_id", "rbx1_arm1_sort"},
                  {"device", device}, {"availability_topic", "rbx1/arm1/status"}, {"payload_available", "online"},
                  {"payload_not_available", "offline"}, {"icon", "mdi:sort"},
                  {"command_topic", "rbx1/arm1/recipe/sort"}, {"payload_press", "PRESS"}, {"qos", 1}}));
  EXPECT_EQ(json::parse(with[7].second)["payload_press"], R"({"cmd":"cancel"})");
  auto without = mqtt::discovery_configs("arm1", "rbx1/arm1", {});
  ASSERT_EQ(without.size(), 10u);
  EXPECT_EQ(without[8].first, with[8].first);
  EXPECT_EQ(without[8].second, "");
  EXPECT_EQ(without[9].second, "");
  EXPECT_EQ(without[0], with[0]);
}
