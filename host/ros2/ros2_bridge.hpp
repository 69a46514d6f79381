// ros2_bridge.hpp - a subscriber of the daemon's bus that publishes the arm to ROS 2 over DDS: joint_states and
// tool_pose from Topic::Status, detections from Topic::Scans, robot_description (the URDF) once, latched.
#pragma once
#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "arm_config.hpp"
#include "bus.hpp"
#include "dds_writers.hpp"
#include "ros2_config.hpp"
#include "types.hpp"

namespace rbx1::ros2 {

// The ROS 2 messages read from the bus (exposed for tests). false when the status has no firmware position.
bool joint_sample_from_status(const arm::ArmConfig& arm, const nlohmann::json& status, JointSample& joints,
                              ToolPoseSample& tool);
// One DetectionSample per object of a scan (README.md: the mapping).
std::vector<DetectionSample> detections_from_scan(const vision::Scan& scan);
// When the status's firmware position was read (its firmware.read_at_ns, Unix time); now when it has none.
Stamp reading_stamp(const nlohmann::json& status);

class Ros2Bridge {
 public:
  Ros2Bridge(const Ros2Config& config, const arm::ArmConfig& arm) : config_(config), arm_(arm) {}
  ~Ros2Bridge() { stop(); }

  // Opens DDS, publishes robot_description and starts reading bus. < 0 + error (names ros2.* keys).
  int start(daemon::Bus& bus, std::string& error);
  void stop();

  struct Counts {
    std::atomic<uint64_t> joint_states{0}, tool_poses{0}, detections{0}, write_errors{0};
  };
  const Counts& counts() const { return counts_; }

 private:
  void run();
  void publish_joints(const Stamp& stamp);

  Ros2Config config_;
  arm::ArmConfig arm_;
  DdsWriters writers_;
  std::shared_ptr<daemon::Subscription> sub_;
  std::thread thread_;
  Counts counts_;
  // The worker's state (only run() touches it).
  bool have_joints_ = false;
  JointSample joints_;
  ToolPoseSample tool_;
  Stamp reading_;     // when joints_ was read from the firmware
  Stamp last_stamp_;  // the last sample's stamp
};

}  // namespace rbx1::ros2
