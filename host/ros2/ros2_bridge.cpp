// ros2_bridge.cpp - the bus to DDS: status -> joint_states + tool_pose, each new firmware reading stamped with
// the time it was read (at most joint_states_hz), the last one repeated every second without one; scans ->
// detections; the URDF once at start.
#include "ros2_bridge.hpp"

#include <numbers>
#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "urdf.hpp"

namespace rbx1::ros2 {

namespace {
using Clock = std::chrono::steady_clock;
constexpr auto kRestPeriod = std::chrono::seconds(1);
bool later(const Stamp& a, const Stamp& b) { return a.sec != b.sec ? a.sec > b.sec : a.nanosec > b.nanosec; }
}  // namespace

Stamp reading_stamp(const nlohmann::json& status) {
  const nlohmann::json& fw = status.contains("firmware") ? status["firmware"] : nlohmann::json();
  if (!fw.is_object() || !fw.contains("read_at_ns") || !fw["read_at_ns"].is_number_integer()) return now_stamp();
  int64_t ns = fw["read_at_ns"].get<int64_t>();
  return Stamp{int32_t(ns / 1000000000), uint32_t(ns % 1000000000)};
}

bool joint_sample_from_status(const arm::ArmConfig& arm, const nlohmann::json& status, JointSample& joints,
                              ToolPoseSample& tool) {
  const nlohmann::json* fw = status.contains("firmware") ? &status["firmware"] : nullptr;
  if (!fw || !fw->is_object() || !fw->contains("position") || !(*fw)["position"].is_array() ||
      (*fw)["position"].size() != size_t(arm::kJoints))
    return false;
  arm::Steps steps;
  for (int j = 0; j < arm::kJoints; ++j) steps[j] = (*fw)["position"][j].get<int32_t>();
  arm::Joints deg = arm::steps_to_joints(arm, steps);  // the exact angles, not status's rounded joints_deg
  joints.names.assign(arm::kUrdfJointNames.begin(), arm::kUrdfJointNames.end());
  joints.positions.clear();
  for (double d : deg) joints.positions.push_back(d * std::numbers::pi / 180);
  if (fw->contains("gripper_us") && (*fw)["gripper_us"].is_number()) {
    joints.names.push_back(arm::kUrdfFingerJoint);
    joints.positions.push_back(arm::finger_position_m(arm.gripper, (*fw)["gripper_us"].get<int>()));
  }
  Eigen::Isometry3d t = arm::fk(arm.links, deg);
  Eigen::Quaterniond q(t.linear());
  tool.position_m = {t.translation().x() / 1000, t.translation().y() / 1000, t.translation().z() / 1000};
  tool.orientation_xyzw = {q.x(), q.y(), q.z(), q.w()};
  return true;
}

std::vector<DetectionSample> detections_from_scan(const vision::Scan& scan) {
  std::vector<DetectionSample> out;
  for (const vision::ScanObject& o : scan.objects) {
    DetectionSample d;
    d.id = std::to_string(o.index);
    if (o.identity.label) {
      d.class_id = *o.identity.label;
      d.score = o.identity.score.value_or(0.0);
    }
    d.cx = o.centroid_px.x;
    d.cy = o.centroid_px.y;
    // The box turned to the grip: x along the closing line, as wide as the opening; y the length that gives the
    // object's area (the detector reports no box).
    d.theta = o.grip.angle_deg * std::numbers::pi / 180;
    d.size_x = o.grip.opening_px;
    d.size_y = d.size_x > 0 ? double(o.area_px) / d.size_x : 0;
    out.push_back(d);
  }
  return out;
}

int Ros2Bridge::start(daemon::Bus& bus, std::string& error) {
  if (writers_.open(config_.domain_id, config_.ns, error) < 0) return -1;
  if (int r = writers_.write_robot_description(arm::urdf(arm_)); r < 0) {
    error = std::string("ros2: cannot publish robot_description: ") + dds_strretcode(r);
    writers_.close();
    return -1;
  }
  sub_ = bus.subscribe(unsigned(daemon::Topic::Status) | unsigned(daemon::Topic::Scans));
  thread_ = std::thread([this] { run(); });
  spdlog::info("ros2: publishing rt/{}/{{joint_states,robot_description,detections,tool_pose}} on DDS domain {}",
               config_.ns, config_.domain_id);
  return 0;
}

void Ros2Bridge::stop() {
  if (sub_) sub_->close();
  if (thread_.joinable()) thread_.join();
  sub_.reset();
  writers_.close();
}

void Ros2Bridge::publish_joints(const Stamp& stamp) {
  bool ok = writers_.write_joint_states(stamp, joints_) >= 0;
  ok = writers_.write_tool_pose(stamp, tool_) >= 0 && ok;
  last_stamp_ = stamp;
  ++counts_.joint_states;
  ++counts_.tool_poses;
  if (!ok) ++counts_.write_errors;
}

void Ros2Bridge::run() {
  const auto fast = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config_.joint_states_hz));
  Clock::time_point last_pub{};
  bool fresh = false;  // joints_ is a new position not written yet
  while (!sub_->closed()) {
    // A new position goes out once the rate allows; when none came for a second, the last one again, stamped with
    // its newest reading, or when written if there was none since (the position still holds; tf2 drops repeated
    // stamps).
    auto now = Clock::now();
    auto due = last_pub + (fresh ? fast : kRestPeriod);
    if (have_joints_ && now >= due) {
      publish_joints(later(reading_, last_stamp_) ? reading_ : now_stamp());
      fresh = false;
      last_pub = now;
      continue;
    }
    int wait_ms = have_joints_ ? int(std::chrono::ceil<std::chrono::milliseconds>(due - now).count()) : 1000;
    daemon::BusMessage m;
    if (!sub_->next(m, std::max(wait_ms, 1))) continue;
    if (m.topic == daemon::Topic::Scans) {
      int r = m.scan ? writers_.write_detections(now_stamp(), detections_from_scan(*m.scan)) : 0;
      ++counts_.detections;
      if (r < 0) ++counts_.write_errors;
      continue;
    }
    JointSample js;
    ToolPoseSample tp;
    if (!joint_sample_from_status(arm_, *m.body, js, tp)) continue;
    Stamp read = reading_stamp(*m.body);
    // A reading no newer than what was written (a repeat went out while it crossed the bus) says nothing new.
    if (have_joints_ && !later(read, last_stamp_)) continue;
    fresh = fresh || !have_joints_ || js.positions != joints_.positions;
    joints_ = std::move(js);
    tool_ = tp;
    reading_ = read;
    have_joints_ = true;
  }
}

}  // namespace rbx1::ros2
