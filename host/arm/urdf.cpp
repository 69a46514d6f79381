// urdf.cpp - writes the URDF: the kinematic chain, limits, tool0, camera_optical, fingers, simple shapes.
#include "urdf.hpp"

#include <numbers>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "kinematics.hpp"

namespace rbx1::arm {

const std::array<const char*, kJoints> kUrdfJointNames = {"joint_1", "joint_2", "joint_3",
                                                         "joint_4", "joint_5", "joint_6"};

namespace {

// URDF needs an effort limit on every moving joint; the config has no torques, so this is a placeholder.
constexpr double kEffortPlaceholder = 10.0;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.15g", std::fabs(v) < 1e-15 ? 0.0 : v);
  return buf;
}
std::string xyz(double x, double y, double z) { return num(x) + " " + num(y) + " " + num(z); }
double m(double mm) { return mm / 1000.0; }

// A shape drawn and collided the same: "<cylinder .../>" or "<box .../>" at origin xyz/rpy in its link.
std::string shape(const std::string& geometry, const std::string& at, const std::string& rpy = "0 0 0") {
  std::string g = "<origin xyz=\"" + at + "\" rpy=\"" + rpy + "\"/><geometry>" + geometry + "</geometry>";
  return "    <visual>" + g + "<material name=\"grey\"/></visual>\n    <collision>" + g + "</collision>\n";
}
std::string cylinder(double radius_m, double length_m) {
  return "<cylinder radius=\"" + num(radius_m) + "\" length=\"" + num(length_m) + "\"/>";
}
std::string box(double x, double y, double z) { return "<box size=\"" + xyz(x, y, z) + "\"/>"; }

std::string link(const std::string& name, const std::string& shapes = "") {
  if (shapes.empty()) return "  <link name=\"" + name + "\"/>\n";
  return "  <link name=\"" + name + "\">\n" + shapes + "  </link>\n";
}

std::string origin(const std::string& at, const std::string& rpy = "0 0 0") {
  return "    <origin xyz=\"" + at + "\" rpy=\"" + rpy + "\"/>\n";
}

std::string joint_head(const std::string& name, const char* type, const std::string& parent,
                       const std::string& child) {
  return "  <joint name=\"" + name + "\" type=\"" + type + "\">\n    <parent link=\"" + parent +
         "\"/>\n    <child link=\"" + child + "\"/>\n";
}

// Joint j (0-based) from link parent to link child at offset z (metres) on the parent's z axis.
std::string revolute(const ArmConfig& cfg, int j, double z_m, const char* axis) {
  const JointConfig& jc = cfg.joints[j];
  std::string parent = j == 0 ? "base_link" : "link_" + std::to_string(j);
  // The firmware's MAX_SPEED in joint radians per second.
  double rad_s = jc.max_speed_steps_s * 2 * std::numbers::pi / (jc.motor_steps * jc.microsteps * jc.reduction);
  return joint_head(kUrdfJointNames[j], "revolute", parent, "link_" + std::to_string(j + 1)) +
         origin(xyz(0, 0, z_m)) + "    <axis xyz=\"" + axis + "\"/>\n    <limit lower=\"" +
         num(jc.min_deg * std::numbers::pi / 180) + "\" upper=\"" + num(jc.max_deg * std::numbers::pi / 180) + "\" effort=\"" +
         num(kEffortPlaceholder) + "\" velocity=\"" + num(rad_s) + "\"/>\n  </joint>\n";
}

std::string fixed(const std::string& name, const std::string& parent, const std::string& child,
                  const Eigen::Isometry3d& t) {
  Eigen::Vector3d p = t.translation();
  // URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll).
  Eigen::Vector3d ypr = t.linear().eulerAngles(2, 1, 0);
  return joint_head(name, "fixed", parent, child) + origin(xyz(p.x(), p.y(), p.z()), xyz(ypr[2], ypr[1], ypr[0])) +
         "  </joint>\n";
}

// camera_optical in tool0: at the scan pose, at the tool point, axes from [arm.camera] (vision_map's mapping):
// image x and y are R(rotation) * F * (1,0) and (0,1) in the base plane, z = x cross y (down when flip_y).
Eigen::Isometry3d camera_in_tool(const ArmConfig& cfg) {
  Eigen::Isometry3d scan = fk(cfg.links, cfg.scan);
  scan.translation() /= 1000.0;
  double a = cfg.camera.rotation_deg * std::numbers::pi / 180, f = cfg.camera.flip_y ? -1.0 : 1.0;
  Eigen::Vector3d x(std::cos(a), std::sin(a), 0), y(-std::sin(a) * f, std::cos(a) * f, 0);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = x.cross(y);
  Eigen::Isometry3d cam = Eigen::Isometry3d::Identity();
  cam.linear() = r;
  cam.translation() = scan.translation();
  return scan.inverse() * cam;
}

std::string fingers(const GripperConfig& g, double tool_m) {
  double depth = m(g.finger_depth_mm), travel = m(g.max_opening_mm) / 2;
  std::string pad = box(0.008, 0.02, depth);
  std::string out;
  for (int side : {1, -1}) {
    std::string name = side > 0 ? "finger_left" : "finger_right";
    out += link(name, shape(pad, xyz(side * 0.004, 0, -depth / 2)));
    out += joint_head(name + "_joint", "prismatic", "link_6", name) + origin(xyz(0, 0, tool_m)) +
           "    <axis xyz=\"" + (side > 0 ? "1 0 0" : "-1 0 0") + "\"/>\n    <limit lower=\"0\" upper=\"" +
           num(travel) + "\" effort=\"" + num(kEffortPlaceholder) + "\" velocity=\"0.1\"/>\n";
    if (side < 0) out += "    <mimic joint=\"finger_left_joint\" multiplier=\"1\" offset=\"0\"/>\n";
    out += "  </joint>\n";
  }
  return out;
}

}  // namespace

std::string urdf(const ArmConfig& cfg) {
  const Links& l = cfg.links;
  const double base = m(l.base_height_mm), upper = m(l.upper_arm_mm), fore = m(l.forearm_mm), tool = m(l.tool_mm);
  const double palm_z = std::max(tool - m(cfg.gripper.finger_depth_mm) - 0.01, 0.0);
  const std::string across_y = "1.5707963267949 0 0";  // a cylinder's z turned onto y: the pitch axes
  std::string s = "<?xml version=\"1.0\"?>\n<!-- Written by `rbx1 urdf` from the [arm] config: metres, radians. -->\n"
                  "<robot name=\"rbx1\">\n  <material name=\"grey\"><color rgba=\"0.7 0.7 0.72 1\"/></material>\n";
  s += link("base_link", shape(cylinder(0.07, base / 2), xyz(0, 0, base / 4)));
  s += link("link_1", shape(cylinder(0.055, base / 2), xyz(0, 0, base * 3 / 4)));
  s += link("link_2", shape(cylinder(0.04, upper), xyz(0, 0, upper / 2)) +
                          shape(cylinder(0.045, 0.09), xyz(0, 0, 0), across_y));
  s += link("link_3", shape(cylinder(0.035, fore), xyz(0, 0, fore / 2)) +
                          shape(cylinder(0.04, 0.08), xyz(0, 0, 0), across_y));
  s += link("link_4", shape(cylinder(0.03, 0.07), xyz(0, 0, 0), across_y));
  s += link("link_5", shape(cylinder(0.028, palm_z), xyz(0, 0, palm_z / 2)));
  s += link("link_6", shape(box(m(cfg.gripper.max_opening_mm) + 0.03, 0.03, 0.02), xyz(0, 0, palm_z)));
  s += link("tool0") + link("camera_optical");
  s += revolute(cfg, 0, 0, "0 0 1") + revolute(cfg, 1, base, "0 1 0") + revolute(cfg, 2, upper, "0 1 0") +
       revolute(cfg, 3, fore, "0 0 1") + revolute(cfg, 4, 0, "0 1 0") + revolute(cfg, 5, 0, "0 0 1");
  Eigen::Isometry3d tool0 = Eigen::Isometry3d::Identity();
  tool0.translation().z() = tool;  // J6 turns about the tool axis: Rz(q6) Tz(tool) = Tz(tool) Rz(q6)
  s += fixed("tool0_joint", "link_6", "tool0", tool0);
  s += fixed("camera_optical_joint", "tool0", "camera_optical", camera_in_tool(cfg));
  s += fingers(cfg.gripper, tool);
  return s + "</robot>\n";
}

double finger_position_m(const GripperConfig& g, int pulse_us) {
  double span = g.open_us - g.closed_us;
  double opening = span == 0 ? 0 : (pulse_us - g.closed_us) / span * g.max_opening_mm;
  return std::clamp(opening, 0.0, g.max_opening_mm) / 2000.0;
}

}  // namespace rbx1::arm
