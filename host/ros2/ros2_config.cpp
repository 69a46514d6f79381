// ros2_config.cpp - reads and range-checks [ros2]; makes the namespace a valid ROS name.
#include "ros2_config.hpp"

#include <unistd.h>

#include <cctype>
#include <cstdlib>

namespace rbx1::ros2 {

namespace {
constexpr int kMaxDomainId = 232;  // the largest domain whose RTPS ports fit (Cyclone's limit too)

// ROS 2 name rules for a namespace: tokens of [A-Za-z0-9_] split by single '/', none starting with a digit, no "__".
bool valid_name(const std::string& s) {
  if (s.empty() || s.front() == '/' || s.back() == '/' || s.find("__") != std::string::npos) return false;
  for (size_t i = 0; i < s.size(); ++i) {
    unsigned char c = s[i];
    bool token_start = i == 0 || s[i - 1] == '/';
    if (c == '/' ? token_start : !(std::isalnum(c) || c == '_') || (token_start && std::isdigit(c))) return false;
  }
  return true;
}
}  // namespace

std::string ros_name(const std::string& text) {
  std::string out;
  for (char c : text) {
    char ch = std::isalnum(static_cast<unsigned char>(c)) ? char(std::tolower(static_cast<unsigned char>(c))) : '_';
    if (ch == '_' && (out.empty() || out.back() == '_')) continue;  // no leading "_", no "__"
    out += ch;
  }
  while (!out.empty() && out.back() == '_') out.pop_back();
  if (out.empty()) return "rbx1";
  if (std::isdigit(static_cast<unsigned char>(out[0]))) out = "arm_" + out;
  return out;
}

std::string host_name() {
  char buf[256] = {};
  if (gethostname(buf, sizeof buf - 1) != 0) return "rbx1";
  return buf;
}

void parse_ros2_config(config::Section s, const std::string& default_ns, Ros2Config& out) {
  out.enabled = s.boolean("enabled", out.enabled);
  int fallback_domain = 0;
  if (const char* env = std::getenv("ROS_DOMAIN_ID"); env && *env && !s.has("domain_id")) {
    char* end = nullptr;
    long v = std::strtol(env, &end, 10);
    if (*end || v < 0 || v > kMaxDomainId)
      s.errors().add(s.path() + ".domain_id", "not set, and $ROS_DOMAIN_ID \"" + std::string(env) + "\" is not 0.." +
                                           std::to_string(kMaxDomainId));
    else
      fallback_domain = int(v);
  }
  out.domain_id = int(s.integer("domain_id", fallback_domain, 0, kMaxDomainId));
  out.ns = s.string("namespace", ros_name(default_ns));
  if (!valid_name(out.ns))
    s.errors().add(s.path() + ".namespace", "\"" + out.ns + "\" is not a ROS namespace (letters, digits, single "
                   "underscores and single slashes between names not starting with a digit); \"" + ros_name(out.ns) +
                   "\" would be");
  out.joint_states_hz = s.number("joint_states_hz", out.joint_states_hz, 1, 1000);
  s.reject_unknown();
}

}  // namespace rbx1::ros2
