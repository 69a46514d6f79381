// ros2_test.cpp - [ros2] parsing, namespace rules, and the bus -> ROS 2 message conversions.
#include <numbers>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include <unistd.h>

#include <chrono>
#include <thread>

#include "joint_steps.hpp"
#include "ros2_msgs.h"
#include "urdf.hpp"
#include "kinematics.hpp"
#include "ros2_bridge.hpp"
#include "ros2_config.hpp"

namespace rbx1::ros2 {
namespace {


bool parse(const std::string& text, Ros2Config& out, config::Errors& errors, const std::string& arm_id = "Lab Arm-2") {
  toml::table root = config::parse_text(text, errors);
  config::Section top(&root, "", errors);
  parse_ros2_config(top.section("ros2"), arm_id, out);
  return errors.ok();
}

TEST(Ros2Config, Defaults) {
  unsetenv("ROS_DOMAIN_ID");
  Ros2Config c;
  config::Errors e;
  ASSERT_TRUE(parse("", c, e)) << e.joined();
  EXPECT_FALSE(c.enabled);
  EXPECT_EQ(c.domain_id, 0);
  EXPECT_EQ(c.ns, "lab_arm_2");
  EXPECT_EQ(c.joint_states_hz, 20);
}

TEST(Ros2Config, DomainFromEnvironmentUnlessSet) {
  setenv("ROS_DOMAIN_ID", "42", 1);
  Ros2Config c;
  config::Errors e;
  ASSERT_TRUE(parse("", c, e)) << e.joined();
  EXPECT_EQ(c.domain_id, 42);
  Ros2Config d;
  ASSERT_TRUE(parse("[ros2]\ndomain_id = 7\n", d, e)) << e.joined();
  EXPECT_EQ(d.domain_id, 7);
  setenv("ROS_DOMAIN_ID", "x9", 1);
  config::Errors bad;
  EXPECT_FALSE(parse("", d, bad));
  EXPECT_NE(bad.joined().find("ros2.domain_id"), std::string::npos) << bad.joined();
  unsetenv("ROS_DOMAIN_ID");
}

TEST(Ros2Config, ErrorsNameTheirKeys) {
  Ros2Config c;
  config::Errors e;
  EXPECT_FALSE(parse("[ros2]\nnamespace = \"9 bad__ns\"\ndomain_id = 300\njoint_states_hz = 0\nrate = 3\n", c, e));
  for (const char* key : {"ros2.namespace", "ros2.domain_id", "ros2.joint_states_hz", "ros2.rate"})
    EXPECT_NE(e.joined().find(key), std::string::npos) << key << " in " << e.joined();
  Ros2Config ok;
  config::Errors none;
  EXPECT_TRUE(parse("[ros2]\nenabled = true\nnamespace = \"Lab/arm_1\"\n", ok, none)) << none.joined();
  EXPECT_EQ(ok.ns, "Lab/arm_1");
}

TEST(Ros2Config, RosName) {
  EXPECT_EQ(ros_name("rbx1"), "rbx1");
  EXPECT_EQ(ros_name("My-Host.local"), "my_host_local");
  EXPECT_EQ(ros_name("__a  b__"), "a_b");
  EXPECT_EQ(ros_name("3dprinter"), "arm_3dprinter");
  EXPECT_EQ(ros_name("..."), "rbx1");
}

TEST(Ros2Convert, JointStatesFromFirmwarePosition) {
  arm::ArmConfig arm = arm::default_arm_config();
  arm::Joints deg{10, -20, 30.5, 0, 95, -45};
  arm::Steps steps = arm::joints_to_steps(arm, deg);
  nlohmann::json status = {{"job", "pick"}, {"joints_deg", {10, -20, 30.5, 0, 95, -45}},
                           {"firmware", {{"position", steps}, {"gripper_us", 1500}}}};
  JointSample js;
  ToolPoseSample tp;
  ASSERT_TRUE(joint_sample_from_status(arm, status, js, tp));
  ASSERT_EQ(js.names.size(), 7u);
  EXPECT_EQ(js.names[0], "joint_1");
  EXPECT_EQ(js.names[6], "finger_left_joint");
  arm::Joints back = arm::steps_to_joints(arm, steps);
  for (int j = 0; j < arm::kJoints; ++j) EXPECT_DOUBLE_EQ(js.positions[j], back[j] * std::numbers::pi / 180);
  EXPECT_NEAR(js.positions[6], 0.0125, 1e-12);  // half of 25 mm
  Eigen::Vector3d p = arm::fk(arm.links, back).translation() / 1000;
  EXPECT_NEAR(tp.position_m[0], p.x(), 1e-12);
  EXPECT_NEAR(tp.position_m[2], p.z(), 1e-12);
  EXPECT_FALSE(joint_sample_from_status(arm, {{"firmware", nullptr}}, js, tp));
}

TEST(Ros2Convert, DetectionsFromScan) {
  auto object = [](int index, std::optional<std::string> label, std::optional<double> score, cv::Point2d c,
                   long area, double angle, double opening) {
    vision::ScanObject o;
    o.index = index;
    o.identity = {label, score};
    o.centroid_px = c;
    o.area_px = area;
    o.grip.angle_deg = angle;
    o.grip.opening_px = opening;
    return o;
  };
  vision::Scan doc;
  doc.objects = {object(0, "bolt", 0.93, {120.5, 80.25}, 600, 90.0, 20.0),
                 object(1, std::nullopt, std::nullopt, {10, 20}, 100, 0.0, 10.0)};
  auto d = detections_from_scan(doc);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].class_id, "bolt");
  EXPECT_EQ(d[0].id, "0");
  EXPECT_DOUBLE_EQ(d[0].score, 0.93);
  EXPECT_DOUBLE_EQ(d[0].cx, 120.5);
  EXPECT_NEAR(d[0].theta, std::numbers::pi / 2, 1e-12);
  EXPECT_DOUBLE_EQ(d[0].size_x, 20);
  EXPECT_DOUBLE_EQ(d[0].size_y, 30);
  EXPECT_EQ(d[1].class_id, "");
  EXPECT_TRUE(detections_from_scan(vision::Scan()).empty());
}

// A reader of rt/<ns>/<topic> on its own participant (the way a ROS 2 node would join).
struct Reader {
  dds_entity_t participant, reader;
  Reader(int domain, const std::string& topic, const dds_topic_descriptor_t* type, bool latched) {
    participant = dds_create_participant(dds_domainid_t(domain), nullptr, nullptr);
    dds_entity_t t = dds_create_topic(participant, type, topic.c_str(), nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, latched ? 1 : 10);
    if (latched) dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
    reader = dds_create_reader(participant, t, qos, nullptr);
    dds_delete_qos(qos);
  }
  ~Reader() { dds_delete(participant); }
  // Takes one sample into sample within timeout_ms; the loan is returned by the caller through dds_return_loan.
  bool take(void** sample, int timeout_ms) {
    dds_sample_info_t info;
    for (int waited = 0; waited < timeout_ms; waited += 5) {
      if (dds_take(reader, sample, &info, 1, 1) > 0 && info.valid_data) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }
};

// In-process DDS: the bridge on a bus; a late reader gets the URDF; a status becomes joint_states.
TEST(Ros2Bridge, PublishesTheBusOverDds) {
  // DDS on loopback only (tests bind nothing else): unicast discovery to 127.0.0.1.
  setenv("CYCLONEDDS_URI",
         "<CycloneDDS><Domain id='any'><General><Interfaces><NetworkInterface name='lo'/></Interfaces>"
         "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
         "<Peers><Peer address='127.0.0.1'/></Peers></Discovery></Domain></CycloneDDS>",
         0);
  Ros2Config cfg;
  cfg.enabled = true;
  cfg.domain_id = 200 + getpid() % 30;
  cfg.ns = "bridge_test_" + std::to_string(getpid());
  arm::ArmConfig arm = arm::default_arm_config();
  daemon::Bus bus;
  Ros2Bridge bridge(cfg, arm);
  std::string error;
  ASSERT_EQ(bridge.start(bus, error), 0) << error;
  Reader desc(cfg.domain_id, "rt/" + cfg.ns + "/robot_description", &std_msgs_msg_dds__String__desc, true);
  void* sample = nullptr;
  ASSERT_TRUE(desc.take(&sample, 5000));
  EXPECT_EQ(std::string(static_cast<std_msgs_msg_dds__String_*>(sample)->data), arm::urdf(arm));
  dds_return_loan(desc.reader, &sample, 1);

  Reader js(cfg.domain_id, "rt/" + cfg.ns + "/joint_states", &sensor_msgs_msg_dds__JointState__desc, false);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // discovery
  arm::Steps steps = arm::joints_to_steps(arm, {5, 10, 15, 20, 25, 30});
  // Stamped with the time the daemon read the position from the firmware, not when the bridge wrote it.
  const int64_t read_at_ns = 1700000000123456789;
  bus.publish(daemon::Topic::Status, {{"job", "pick"},
                                      {"firmware", {{"position", steps}, {"gripper_us", 2000}, {"read_at_ns", read_at_ns}}}});
  sample = nullptr;
  ASSERT_TRUE(js.take(&sample, 5000));
  auto* m = static_cast<sensor_msgs_msg_dds__JointState_*>(sample);
  ASSERT_EQ(m->position._length, 7u);
  arm::Joints deg = arm::steps_to_joints(arm, steps);
  EXPECT_DOUBLE_EQ(m->position._buffer[2], deg[2] * std::numbers::pi / 180);
  EXPECT_STREQ(m->name._buffer[6], "finger_left_joint");
  EXPECT_STREQ(m->header.frame_id, "");
  EXPECT_EQ(m->header.stamp.sec, 1700000000);
  EXPECT_EQ(m->header.stamp.nanosec, 123456789u);
  EXPECT_DOUBLE_EQ(m->position._buffer[6], 0.025);
  dds_return_loan(js.reader, &sample, 1);
  bridge.stop();
  EXPECT_GE(bridge.counts().joint_states.load(), 1u);
  EXPECT_EQ(bridge.counts().write_errors.load(), 0u);
}

}  // namespace
}  // namespace rbx1::ros2
