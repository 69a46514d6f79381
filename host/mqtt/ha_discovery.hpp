// ha_discovery.hpp - Home Assistant MQTT discovery: the arm as one device (sensors, binary sensors, buttons), each
// a retained config under homeassistant/, available while <prefix>/status is "online".
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace rbx1::mqtt {

inline constexpr const char* kHaStatusTopic = "homeassistant/status";  // "online" when Home Assistant (re)starts

// (topic, retained JSON payload) for every entity of the arm.
std::vector<std::pair<std::string, std::string>> discovery_configs(const std::string& arm_id, const std::string& prefix);

}  // namespace rbx1::mqtt
