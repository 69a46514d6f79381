// ha_discovery.cpp - the discovery configs: state, job and picks today as sensors, fault and busy as binary
// sensors, home, stop and cancel as buttons publishing their request on <prefix>/cmd; the saved recipes as a select
// (the choice only) and a Sort button that starts a sort with the chosen one.
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
  const char* command_leaf;    // buttons: the topic pressed (under the prefix)
  const char* press;           // buttons: the payload published there
  const char* icon;
};

constexpr Entity kEntities[] = {
    {"sensor", "state", "State", "{{ value_json.mode }}", nullptr, nullptr, "mdi:robot-industrial"},
    {"sensor", "job", "Job", "{{ value_json.job if value_json.job else 'idle' }}", nullptr, nullptr, "mdi:briefcase"},
    {"sensor", "picks_today", "Picks today", "{{ value_json.picks_today }}", nullptr, nullptr, "mdi:counter"},
    {"binary_sensor", "fault", "Fault", "{{ 'ON' if value_json.mode in ['fault', 'estop'] else 'OFF' }}", nullptr,
     nullptr, "mdi:alert"},
    {"binary_sensor", "busy", "Busy", "{{ 'ON' if value_json.job else 'OFF' }}", nullptr, nullptr,
     "mdi:progress-clock"},
    {"button", "home", "Home", nullptr, "cmd", R"({"cmd":"home"})", "mdi:home"},
    {"button", "stop", "Stop (protective, not an emergency stop)", nullptr, "cmd", R"({"cmd":"estop"})", "mdi:stop"},
    {"button", "cancel", "Cancel the sort", nullptr, "cmd", R"({"cmd":"cancel"})", "mdi:cancel"},
};
// Only while recipes are saved: the select of recipes and the button that starts a sort with the chosen one.
constexpr Entity kSortButton{"button", "sort", "Sort (the chosen recipe)", nullptr, kSortLeaf, "PRESS", "mdi:sort"};
constexpr const char* kSelectObject = "recipe";
}  // namespace

std::vector<std::pair<std::string, std::string>> discovery_configs(const std::string& arm_id, const std::string& prefix,
                                                                   const std::vector<std::string>& recipes) {
  std::string node = node_id(arm_id);
  nlohmann::json device{{"identifiers", {"rbx1_" + node}}, {"name", "RBX1 " + arm_id}, {"manufacturer", "RBX1 project"},
                        {"model", "RBX1 arm (rbx1d)"}};
  auto config_topic = [&](const char* component, const char* object) {
    return std::string("homeassistant/") + component + "/" + node + "/" + object + "/config";
  };
  auto common = [&](const char* object, const char* name, const char* icon) {
    return nlohmann::json{{"name", name},
                          {"unique_id", "rbx1_" + node + "_" + object},
                          {"object_id", "rbx1_" + node + "_" + object},
                          {"device", device},
                          {"availability_topic", prefix + "/status"},
                          {"payload_available", "online"},
                          {"payload_not_available", "offline"},
                          {"icon", icon}};
  };
  auto entity = [&](const Entity& e) {
    nlohmann::json c = common(e.object, e.name, e.icon);
    if (e.value_template) {
      c["state_topic"] = prefix + "/state";
      c["value_template"] = e.value_template;
    }
    if (e.press) {
      c["command_topic"] = prefix + "/" + e.command_leaf;
      c["payload_press"] = e.press;
      c["qos"] = 1;
    }
    return c.dump();
  };
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& e : kEntities) out.emplace_back(config_topic(e.component, e.object), entity(e));
  // No recipe saved: the select and the Sort button are removed (an empty retained config), not left stale.
  std::string select, sort;
  if (!recipes.empty()) {
    nlohmann::json c = common(kSelectObject, "Recipe (chooses only; Sort starts it)", "mdi:clipboard-list");
    c["command_topic"] = prefix + "/" + kRecipeSetLeaf;
    c["state_topic"] = prefix + "/" + kRecipeLeaf;
    c["options"] = recipes;
    c["qos"] = 1;
    select = c.dump();
    sort = entity(kSortButton);
  }
  out.emplace_back(config_topic("select", kSelectObject), select);
  out.emplace_back(config_topic(kSortButton.component, kSortButton.object), sort);
  return out;
}

}  // namespace rbx1::mqtt
