// ros2_config.hpp - the [ros2] table: DDS publishing on or off, the domain, the ROS namespace, the joint_states rate.
#pragma once
#include <string>

#include "config.hpp"

namespace rbx1::ros2 {

struct Ros2Config {
  bool enabled = false;
  int domain_id = 0;            // default: $ROS_DOMAIN_ID, else 0 (Cyclone does not read that variable itself)
  std::string ns;               // ROS namespace without leading slash: topics rt/<ns>/joint_states ...
  double joint_states_hz = 20;  // while the arm moves; 1 Hz at rest
};

// A valid ROS name token from any text ("RBX1 lab-2" -> "rbx1_lab_2"): lower case, [a-z0-9_], no "__", not
// starting with a digit ("arm_" is put in front), "rbx1" when nothing is left.
std::string ros_name(const std::string& text);

// Reads [ros2]. default_ns: what the namespace is when the key is absent (the arm's id: [daemon] arm_id, or the
// host name), made a valid ROS name. Errors name the key (ros2.namespace, ros2.domain_id, ...), also a bad
// $ROS_DOMAIN_ID when it is the default.
void parse_ros2_config(config::Section ros2, const std::string& default_ns, Ros2Config& out);

// The host name (gethostname), the namespace's default while [daemon] has no arm_id.
std::string host_name();

}  // namespace rbx1::ros2
