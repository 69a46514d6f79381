// ha_discovery.hpp - Home Assistant MQTT discovery: the arm as one device (sensors, binary sensors, buttons, the
// select of saved recipes), each a retained config under homeassistant/, available while <prefix>/status is "online".
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace rbx1::mqtt {

inline constexpr const char* kHaStatusTopic = "homeassistant/status";  // "online" when Home Assistant (re)starts
// Under the prefix: the recipe chosen in the select (retained; the select's state), the select's command (a
// recipe's name: chooses, never moves the arm), and the Sort button's command (a sort with the chosen recipe).
inline constexpr const char* kRecipeLeaf = "recipe";
inline constexpr const char* kRecipeSetLeaf = "recipe/set";
inline constexpr const char* kSortLeaf = "recipe/sort";

// (topic, retained JSON payload) for every entity of the arm. recipes: the saved recipes' names, the select's
// options; when there are none the select's and the Sort button's payloads are "" (removes them from Home Assistant).
std::vector<std::pair<std::string, std::string>> discovery_configs(const std::string& arm_id, const std::string& prefix,
                                                                   const std::vector<std::string>& recipes);

}  // namespace rbx1::mqtt
