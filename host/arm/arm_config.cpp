// arm_config.cpp - reads and range-checks the [arm] table; every error names its key.
#include "arm_config.hpp"

#include <cstdio>
#include <string>
#include <vector>

namespace rbx1::arm {

namespace {

using rbx1::config::Section;

const char* const kJointNames[kJoints] = {"base yaw", "shoulder", "elbow", "forearm roll", "wrist pitch", "wrist roll"};

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

void read_links(Section s, Links& l) {
  l.base_height_mm = s.number("base_height_mm", l.base_height_mm, 0.0, 2000.0);
  l.upper_arm_mm = s.number("upper_arm_mm", l.upper_arm_mm, 10.0, 2000.0);
  l.forearm_mm = s.number("forearm_mm", l.forearm_mm, 10.0, 2000.0);
  l.tool_mm = s.number("tool_mm", l.tool_mm, 0.0, 1000.0);
  s.reject_unknown();
}

void read_joint(Section s, JointConfig& j) {
  j.reduction = s.number("reduction", j.reduction, 0.01, 1000.0);
  j.motor_steps = int(s.integer("motor_steps", j.motor_steps, 1, 1000));
  j.microsteps = int(s.integer("microsteps", j.microsteps, 1, 256));
  // +-360 keeps every step count of the range within int32 for any reduction and microstepping allowed above.
  const double default_min = j.min_deg, default_max = j.max_deg;
  j.min_deg = s.number("min_deg", j.min_deg, -360.0, 360.0);
  j.max_deg = s.number("max_deg", j.max_deg, -360.0, 360.0);
  int64_t dir = s.integer("direction", j.direction, -1, 1);
  if (dir == 0) {
    s.errors().add(s.path() + ".direction", "must be 1 or -1");
  } else {
    j.direction = int(dir);
  }
  j.zero_deg = s.number("zero_deg", j.zero_deg, -360.0, 360.0);
  // The ranges of the firmware's MAX_SPEED and ACCEL keys (PROTOCOL.md).
  j.max_speed_steps_s = int(s.integer("max_speed_steps_s", j.max_speed_steps_s, 1, 20000));
  j.accel_steps_s2 = int(s.integer("accel_steps_s2", j.accel_steps_s2, 1, 200000));
  if (j.min_deg >= j.max_deg) {
    s.errors().add(s.path() + ".min_deg", "must be below max_deg (" + fmt(j.min_deg) + " >= " + fmt(j.max_deg) + ")");
    j.min_deg = default_min;  // keep the defaults, so checks against the limits do not report this again
    j.max_deg = default_max;
  }
  s.reject_unknown();
}

void read_gripper(Section s, GripperConfig& g) {
  g.closed_us = int(s.integer("closed_us", g.closed_us, 500, 2500));
  g.open_us = int(s.integer("open_us", g.open_us, 500, 2500));
  g.max_opening_mm = s.number("max_opening_mm", g.max_opening_mm, 1.0, 500.0);
  g.margin_mm = s.number("margin_mm", g.margin_mm, 0.0, 100.0);
  g.finger_depth_mm = s.number("finger_depth_mm", g.finger_depth_mm, 0.0, 200.0);
  g.dwell_ms = int(s.integer("dwell_ms", g.dwell_ms, 0, 65535));
  if (g.closed_us == g.open_us) s.errors().add(s.path() + ".open_us", "must differ from closed_us");
  s.reject_unknown();
}

void read_pose(Section& s, const char* key, Joints& pose) {
  std::vector<double> v = s.numbers(key, std::vector<double>(pose.begin(), pose.end()), -360.0, 360.0);
  for (int i = 0; i < kJoints; ++i) pose[i] = v[i];
}

void read_camera(Section s, CameraMount& c) {
  std::vector<double> o = s.numbers("origin_mm", {c.origin_x_mm, c.origin_y_mm}, -5000.0, 5000.0);
  c.origin_x_mm = o[0];
  c.origin_y_mm = o[1];
  c.rotation_deg = s.number("rotation_deg", c.rotation_deg, -360.0, 360.0);
  c.flip_y = s.boolean("flip_y", c.flip_y);
  s.reject_unknown();
}

void read_place(Section s, Place& p) {
  for (const char* required : {"x_mm", "y_mm"})
    if (!s.has(required)) s.errors().add(s.path() + "." + required, "missing");
  p.x_mm = s.number("x_mm", p.x_mm, -5000.0, 5000.0);
  p.y_mm = s.number("y_mm", p.y_mm, -5000.0, 5000.0);
  p.z_mm = s.number("z_mm", p.z_mm, -5000.0, 5000.0);
  p.yaw_deg = s.number("yaw_deg", p.yaw_deg, -360.0, 360.0);
  s.reject_unknown();
}

void read_places(Section s, std::map<std::string, Place>& places) {
  std::map<std::string, Place> out;
  for (const std::string& name : s.keys()) {
    Place p;
    read_place(s.section(name), p);
    out[name] = p;
  }
  s.reject_unknown();
  places = std::move(out);  // a [arm.places] table replaces the default set
}

void read_heights(Section s, Heights& h) {
  h.table_z_mm = s.number("table_z_mm", h.table_z_mm, -2000.0, 2000.0);
  h.approach_clearance_mm = s.number("approach_clearance_mm", h.approach_clearance_mm, 0.0, 500.0);
  h.lift_clearance_mm = s.number("lift_clearance_mm", h.lift_clearance_mm, 0.0, 500.0);
  h.finger_clearance_mm = s.number("finger_clearance_mm", h.finger_clearance_mm, 0.0, 100.0);
  s.reject_unknown();
}

void read_speeds(Section s, Speeds& v) {
  v.joint_speed_deg_s = s.number("joint_speed_deg_s", v.joint_speed_deg_s, 0.1, 360.0);
  v.min_move_ms = int(s.integer("min_move_ms", v.min_move_ms, 0, 60000));
  s.reject_unknown();
}

}  // namespace

const char* joint_name(int j) { return j >= 0 && j < kJoints ? kJointNames[j] : "?"; }

ArmConfig default_arm_config() { return ArmConfig{}; }

bool parse_arm_config(Section arm, ArmConfig& out) {
  rbx1::config::Errors& errors = arm.errors();
  const size_t errors_before = errors.messages().size();
  ArmConfig c;
  read_links(arm.section("links"), c.links);
  Section joints = arm.section("joints");
  for (int j = 0; j < kJoints; ++j) read_joint(joints.section("j" + std::to_string(j + 1)), c.joints[j]);
  joints.reject_unknown();
  read_gripper(arm.section("gripper"), c.gripper);
  Section poses = arm.section("poses");
  read_pose(poses, "home", c.home);
  read_pose(poses, "scan", c.scan);
  poses.reject_unknown();
  read_camera(arm.section("camera"), c.camera);
  if (arm.has("places")) read_places(arm.section("places"), c.places);  // else the default places stay
  read_heights(arm.section("heights"), c.heights);
  read_speeds(arm.section("speeds"), c.speeds);
  arm.reject_unknown();

  // Consistency between keys: poses within the joint limits; retreat must lift the open fingers clear.
  auto check_pose = [&](const char* key, const Joints& pose) {
    for (int j = 0; j < kJoints; ++j) {
      const JointConfig& jc = c.joints[j];
      if (pose[j] < jc.min_deg || pose[j] > jc.max_deg)
        errors.add(poses.path() + "." + key + "[" + std::to_string(j) + "]",
                   "J" + std::to_string(j + 1) + " (" + joint_name(j) + ") at " + fmt(pose[j]) +
                       " deg is outside its limits [" + fmt(jc.min_deg) + ", " + fmt(jc.max_deg) + "]");
    }
  };
  check_pose("home", c.home);
  check_pose("scan", c.scan);
  if (c.heights.approach_clearance_mm <= c.gripper.finger_depth_mm)
    errors.add(arm.path() + ".heights.approach_clearance_mm",
               "must exceed gripper.finger_depth_mm (" + fmt(c.gripper.finger_depth_mm) + ") so a retreat clears the fingers");
  out = std::move(c);
  return errors.messages().size() == errors_before;
}

}  // namespace rbx1::arm
