// dds_writers.hpp - the DDS side: one Cyclone DDS participant and the four ROS 2 topics' writers, filled from
// plain values (no JSON here; ros2_bridge.cpp turns the bus's messages into these).
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <dds/dds.h>

namespace rbx1::ros2 {

// ROS time (builtin_interfaces/Time): the Unix epoch, as ROS 2 uses it.
struct Stamp {
  int32_t sec = 0;
  uint32_t nanosec = 0;
};
Stamp now_stamp();

struct JointSample {
  std::vector<std::string> names;
  std::vector<double> positions;  // radians; metres for the finger
};

struct ToolPoseSample {
  std::array<double, 3> position_m{};
  std::array<double, 4> orientation_xyzw{0, 0, 0, 1};
};

// One image-space detection (vision_msgs/Detection2D): box centre and size in pixels, theta in radians.
struct DetectionSample {
  std::string id, class_id;  // class_id "" = unidentified: no hypothesis
  double score = 0;
  double cx = 0, cy = 0, theta = 0, size_x = 0, size_y = 0;
};

class DdsWriters {
 public:
  DdsWriters() = default;
  DdsWriters(const DdsWriters&) = delete;
  DdsWriters& operator=(const DdsWriters&) = delete;
  ~DdsWriters() { close(); }

  // Participant on domain_id, topics rt/<ns>/{joint_states, robot_description, detections, tool_pose}.
  // < 0 + error naming the domain or the topic.
  int open(int domain_id, const std::string& ns, std::string& error);
  void close();  // deletes the participant and everything under it

  // Each returns the dds_write result (0 or a negative DDS_RETCODE).
  int write_joint_states(const Stamp& t, const JointSample& s);
  int write_robot_description(const std::string& urdf);
  int write_tool_pose(const Stamp& t, const ToolPoseSample& p);
  int write_detections(const Stamp& t, const std::vector<DetectionSample>& d);

 private:
  dds_entity_t participant_ = 0;
  dds_entity_t joint_states_ = 0, description_ = 0, detections_ = 0, tool_pose_ = 0;
};

}  // namespace rbx1::ros2
