// ha_discovery.cpp - the discovery configs: state, job and picks today as sensors, fault and busy as binary
// sensors, home and stop as buttons publishing their request on <prefix>/cmd.
#include "ha_discovery.hpp"

#include <nlohmann/json.hpp>

namespace rbx1::mqtt {

namespace {
// Home Assistant's node and object ids: [a-zA-Z0-9_-] only.
std::string node_id(const std::string& arm_id) {
  std::string n = arm_id;
  for (char& c : n)
    if (!(isalnum((unsigned char)c) || c == '_' || c == '-')) c = '_';
  return n;
}

struct Entity {
  const char* component;
  const char* object;
  const char* name;
  const char* value_template;  // sensors: from the state document
  const char* press;           // buttons: the request published on cmd
  const char* icon;
};

constexpr Entity kEntities[] = {
    {"sensor", "state", "State", "{{ value_json.mode }}", nullptr, "mdi:robot-industrial"},
    {"sensor", "job", "Job", "{{ value_json.job if value_json.job else 'idle' }}", nullptr, "mdi:briefcase"},
    {"sensor", "picks_today", "Picks today", "{{ value_json.picks_today }}", nullptr, "mdi:counter"},
    {"binary_sensor", "fault", "Fault", "{{ 'ON' if value_json.mode in ['fault', 'estop'] else 'OFF' }}", nullptr,
     "mdi:alert"},
    {"binary_sensor", "busy", "Busy", "{{ 'ON' if value_json.job else 'OFF' }}", nullptr, "mdi:progress-clock"},
    {"button", "home", "Home", nullptr, R"({"cmd":"home"})", "mdi:home"},
    {"button", "stop", "Stop (protective, not an emergency stop)", nullptr, R"({"cmd":"estop"})", "mdi:stop"},
};
}  // namespace

std::vector<std::pair<std::string, std::string>> discovery_configs(const std::string& arm_id, const std::string& prefix) {
  std::string node = node_id(arm_id);
  nlohmann::json device{{"identifiers", {"rbx1_" + node}}, {"name", "RBX1 " + arm_id}, {"manufacturer", "RBX1 project"},
                        {"model", "RBX1 arm (rbx1d)"}};
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& e : kEntities) {
    nlohmann::json c{{"name", e.name},
                     {"unique_id", "rbx1_" + node + "_" + e.object},
                     {"object_id", "rbx1_" + node + "_" + e.object},
                     {"device", device},
                     {"availability_topic", prefix + "/status"},
                     {"payload_available", "online"},
                     {"payload_not_available", "offline"},
                     {"icon", e.icon}};
    if (e.value_template) {
      c["state_topic"] = prefix + "/state";
      c["value_template"] = e.value_template;
    }
    if (e.press) {
      c["command_topic"] = prefix + "/cmd";
      c["payload_press"] = e.press;
      c["qos"] = 1;
    }
    out.emplace_back(std::string("homeassistant/") + e.component + "/" + node + "/" + e.object + "/config", c.dump());
  }
  return out;
}

}  // namespace rbx1::mqtt
