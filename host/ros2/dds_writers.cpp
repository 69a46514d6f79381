// dds_writers.cpp - Cyclone DDS C API: participant, topics with ROS 2's names and QoS, and the samples' filling.
#include "dds_writers.hpp"

#include <chrono>

#include "ros2_msgs.h"

namespace rbx1::ros2 {

namespace {

// Strings in the generated C types are char*; the writer only reads them during dds_write.
char* str(const std::string& s) { return const_cast<char*>(s.c_str()); }

std_msgs_msg_dds__Header_ header(const Stamp& t, const std::string& frame) {
  std_msgs_msg_dds__Header_ h{};
  h.stamp.sec = t.sec;
  h.stamp.nanosec = t.nanosec;
  h.frame_id = str(frame);
  return h;
}

// Static: the samples point into these strings until dds_write returns.
const std::string kBaseFrame = "base_link", kCameraFrame = "camera_optical", kNoFrame;

}  // namespace

Stamp now_stamp() {
  auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch());
  return Stamp{int32_t(ns.count() / 1000000000), uint32_t(ns.count() % 1000000000)};
}

int DdsWriters::open(int domain_id, const std::string& ns, std::string& error) {
  close();
  participant_ = dds_create_participant(dds_domainid_t(domain_id), nullptr, nullptr);
  if (participant_ < 0) {
    error = "ros2: cannot create a DDS participant on domain " + std::to_string(domain_id) + " (ros2.domain_id): " +
            dds_strretcode(participant_);
    participant_ = 0;
    return -1;
  }
  struct Spec {
    dds_entity_t* writer;
    const dds_topic_descriptor_t* type;
    const char* name;
    bool latched;  // transient local, depth 1 (robot_description); else volatile, keep last 10
  };
  const Spec specs[] = {{&joint_states_, &sensor_msgs_msg_dds__JointState__desc, "joint_states", false},
                        {&description_, &std_msgs_msg_dds__String__desc, "robot_description", true},
                        {&detections_, &vision_msgs_msg_dds__Detection2DArray__desc, "detections", false},
                        {&tool_pose_, &geometry_msgs_msg_dds__PoseStamped__desc, "tool_pose", false}};
  for (const Spec& s : specs) {
    std::string name = "rt/" + ns + "/" + s.name;  // ROS 2's topic prefix for DDS
    dds_entity_t topic = dds_create_topic(participant_, s.type, name.c_str(), nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, s.latched ? 1 : 10);
    dds_qset_durability(qos, s.latched ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
    *s.writer = topic < 0 ? topic : dds_create_writer(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    if (*s.writer < 0) {
      error = "ros2: cannot create the DDS writer of " + name + ": " + dds_strretcode(*s.writer);
      close();
      return -1;
    }
  }
  return 0;
}

void DdsWriters::close() {
  if (participant_ > 0) dds_delete(participant_);
  participant_ = joint_states_ = description_ = detections_ = tool_pose_ = 0;
}

int DdsWriters::write_joint_states(const Stamp& t, const JointSample& s) {
  std::vector<char*> names;
  for (const std::string& n : s.names) names.push_back(str(n));
  sensor_msgs_msg_dds__JointState_ m{};
  m.header = header(t, kNoFrame);  // joint_states carry no frame
  m.name._length = m.name._maximum = uint32_t(names.size());
  m.name._buffer = names.data();
  m.position._length = m.position._maximum = uint32_t(s.positions.size());
  m.position._buffer = const_cast<double*>(s.positions.data());
  return dds_write(joint_states_, &m);
}

int DdsWriters::write_robot_description(const std::string& urdf) {
  std_msgs_msg_dds__String_ m{str(urdf)};
  return dds_write(description_, &m);
}

int DdsWriters::write_tool_pose(const Stamp& t, const ToolPoseSample& p) {
  geometry_msgs_msg_dds__PoseStamped_ m{};
  m.header = header(t, kBaseFrame);
  m.pose.position = {p.position_m[0], p.position_m[1], p.position_m[2]};
  m.pose.orientation = {p.orientation_xyzw[0], p.orientation_xyzw[1], p.orientation_xyzw[2], p.orientation_xyzw[3]};
  return dds_write(tool_pose_, &m);
}

int DdsWriters::write_detections(const Stamp& t, const std::vector<DetectionSample>& d) {
  std::vector<vision_msgs_msg_dds__Detection2D_> dets(d.size());
  std::vector<vision_msgs_msg_dds__ObjectHypothesisWithPose_> hyps(d.size());
  for (size_t i = 0; i < d.size(); ++i) {
    auto& out = dets[i];
    out = {};
    out.header = header(t, kCameraFrame);
    out.id = str(d[i].id);
    out.bbox.center.position = {d[i].cx, d[i].cy};
    out.bbox.center.theta = d[i].theta;
    out.bbox.size_x = d[i].size_x;
    out.bbox.size_y = d[i].size_y;
    hyps[i] = {};
    hyps[i].hypothesis.class_id = str(d[i].class_id);
    hyps[i].hypothesis.score = d[i].score;
    hyps[i].pose.pose.orientation.w = 1;
    if (!d[i].class_id.empty()) {
      out.results._length = out.results._maximum = 1;
      out.results._buffer = &hyps[i];
    }
  }
  vision_msgs_msg_dds__Detection2DArray_ m{};
  m.header = header(t, kCameraFrame);
  m.detections._length = m.detections._maximum = uint32_t(dets.size());
  m.detections._buffer = dets.data();
  return dds_write(detections_, &m);
}

}  // namespace rbx1::ros2
