// kinematics.cpp - the kinematic chain, the closed-form top-down IK and the choice among its solutions.
#include "kinematics.hpp"

#include <numbers>
#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rbx1::arm {

namespace {

constexpr double kLimitSlack = 1e-9;  // degrees: a solution landing exactly on a limit is within it

double rad(double deg) { return deg * std::numbers::pi / 180.0; }
double deg(double rad) { return rad * 180.0 / std::numbers::pi; }

Eigen::AngleAxisd rot_z(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitZ()); }
Eigen::AngleAxisd rot_y(double d) { return Eigen::AngleAxisd(rad(d), Eigen::Vector3d::UnitY()); }

// The equivalent of v (mod period) within [lo, hi] nearest to current; v itself when none fits.
double fold(double v, double period, double current, double lo, double hi) {
  double best = v;
  double best_dist = INFINITY;
  double k_lo = std::ceil((lo - kLimitSlack - v) / period), k_hi = std::floor((hi + kLimitSlack - v) / period);
  for (double k = k_lo; k <= k_hi; k += 1.0) {
    double c = v + k * period;
    if (std::fabs(c - current) < best_dist) {
      best = c;
      best_dist = std::fabs(c - current);
    }
  }
  return best;
}

double distance2(const Joints& a, const Joints& b) {
  double s = 0;
  for (int i = 0; i < kJoints; ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return s;
}

std::string num(double v, const char* f = "%.2f") {
  char buf[48];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

double normalize_deg(double d) {
  double r = std::fmod(d, 360.0);
  if (r <= -180.0) r += 360.0;
  if (r > 180.0) r -= 360.0;
  return r;
}

double normalize_axis_deg(double d) {
  double r = std::fmod(d, 180.0);
  if (r <= -90.0) r += 180.0;
  if (r > 90.0) r -= 180.0;
  return r;
}

Eigen::Isometry3d fk(const Links& l, const Joints& q) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.rotate(rot_z(q[0]));
  t.translate(Eigen::Vector3d(0, 0, l.base_height_mm));
  t.rotate(rot_y(q[1]));
  t.translate(Eigen::Vector3d(0, 0, l.upper_arm_mm));
  t.rotate(rot_y(q[2]));
  t.translate(Eigen::Vector3d(0, 0, l.forearm_mm));
  t.rotate(rot_z(q[3]));
  t.rotate(rot_y(q[4]));
  t.translate(Eigen::Vector3d(0, 0, l.tool_mm));
  t.rotate(rot_z(q[5]));
  return t;
}

ToolPose tool_pose(const Links& links, const Joints& q) {
  Eigen::Isometry3d t = fk(links, q);
  ToolPose p;
  p.x_mm = t.translation().x();
  p.y_mm = t.translation().y();
  p.z_mm = t.translation().z();
  Eigen::Vector3d x = t.linear().col(0), z = t.linear().col(2);
  p.yaw_deg = normalize_axis_deg(deg(std::atan2(x.y(), x.x())));
  p.tilt_deg = deg(std::atan2(std::hypot(z.x(), z.y()), -z.z()));  // exact near 0, unlike acos
  return p;
}

bool check_limits(const ArmConfig& cfg, const Joints& q, std::string& error) {
  for (int j = 0; j < kJoints; ++j) {
    const JointConfig& jc = cfg.joints[j];
    if (!std::isfinite(q[j])) {
      error = "J" + std::to_string(j + 1) + " (" + joint_name(j) + ") has no finite angle";
      return false;
    }
    bool low = q[j] < jc.min_deg - kLimitSlack, high = q[j] > jc.max_deg + kLimitSlack;
    if (!low && !high) continue;
    std::string key = std::string(low ? "min_deg" : "max_deg");
    error = "J" + std::to_string(j + 1) + " (" + joint_name(j) + ") at " + num(q[j]) + " deg is " +
            (low ? "below" : "above") + " its limit " + key + " = " + num(low ? jc.min_deg : jc.max_deg, "%g") +
            " (arm.joints.j" + std::to_string(j + 1) + "." + key + ")";
    return false;
  }
  return true;
}

bool ik_solutions(const ArmConfig& cfg, const Grasp& g, const Joints& current, std::vector<IkSolution>& out,
                  std::string& error) {
  out.clear();
  if (!std::isfinite(g.x_mm) || !std::isfinite(g.y_mm) || !std::isfinite(g.z_mm) || !std::isfinite(g.yaw_deg)) {
    error = "target has a coordinate or yaw that is not a finite number";
    return false;
  }
  const Links& l = cfg.links;
  const double l2 = l.upper_arm_mm, l3 = l.forearm_mm;
  // Top-down: the wrist-pitch axis sits tool_mm straight above the tool point, in the vertical plane of J1.
  const double wz = g.z_mm + l.tool_mm;
  const double rho = std::hypot(g.x_mm, g.y_mm);
  const double h = wz - l.base_height_mm;
  const double dist = std::hypot(rho, h);
  double d = (dist * dist - l2 * l2 - l3 * l3) / (2 * l2 * l3);
  auto where = [&] {
    return "target (" + num(g.x_mm, "%.1f") + ", " + num(g.y_mm, "%.1f") + ", " + num(g.z_mm, "%.1f") + ") mm";
  };
  if (d > 1.0 + 1e-12) {
    error = where() + " is out of reach: the wrist would be " + num(dist, "%.1f") +
            " mm from the shoulder, the arm reaches " + num(l2 + l3, "%.1f") + " mm";
    return false;
  }
  if (d < -1.0 - 1e-12) {
    error = where() + " is too close to the shoulder: the wrist would be " + num(dist, "%.1f") +
            " mm from it, at least " + num(std::fabs(l2 - l3), "%.1f") + " mm needed";
    return false;
  }
  d = std::clamp(d, -1.0, 1.0);
  // Straight above the base the base angle is free: keep the current one.
  const double q1_front = rho < 1e-9 ? current[0] : deg(std::atan2(g.y_mm, g.x_mm));
  for (int branch : {1, -1}) {
    const double r = branch * rho;  // horizontal distance along the arm's plane (negative: reaching back)
    const double q1 = branch > 0 ? q1_front : q1_front + 180.0;
    for (int elbow : {1, -1}) {
      const double q3 = elbow * deg(std::acos(d));
      const double q2 = deg(std::atan2(r, h) - std::atan2(l3 * std::sin(rad(q3)), l2 + l3 * std::cos(rad(q3))));
      const double pitch = 180.0 - q2 - q3;  // q2 + q3 + q5 = 180: the tool points straight down
      for (bool flip : {false, true}) {
        const double q4 = flip ? 180.0 : 0.0;
        const double q5 = flip ? -pitch : pitch;
        // J6 from the orientation left over after J1..J5: Rz(q6) = R05^T * R_target.
        Eigen::Matrix3d r05 = (rot_z(q1) * rot_y(q2 + q3) * rot_z(q4) * rot_y(q5)).toRotationMatrix();
        Eigen::Matrix3d target;
        const double c = std::cos(rad(g.yaw_deg)), s = std::sin(rad(g.yaw_deg));
        target << c, s, 0, s, -c, 0, 0, 0, -1;  // columns: closing line, z x closing line, straight down
        Eigen::Matrix3d m = r05.transpose() * target;
        const double q6 = deg(std::atan2(m(1, 0), m(0, 0)));
        Joints raw{q1, q2, q3, q4, q5, q6};
        const double periods[kJoints] = {360, 360, 360, 360, 360, 180};
        IkSolution sol;
        for (int j = 0; j < kJoints; ++j)
          sol.joints[j] = fold(normalize_deg(raw[j]), periods[j], current[j], cfg.joints[j].min_deg,
                               cfg.joints[j].max_deg);
        sol.elbow_up = branch * q3 >= 0;
        sol.wrist_flipped = flip;
        sol.reaches_back = branch < 0;
        check_limits(cfg, sol.joints, sol.limit_error);
        out.push_back(sol);
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [&](const IkSolution& a, const IkSolution& b) {
    if (a.elbow_up != b.elbow_up) return a.elbow_up;
    if (a.wrist_flipped != b.wrist_flipped) return !a.wrist_flipped;
    return distance2(a.joints, current) < distance2(b.joints, current);
  });
  return true;
}

bool ik(const ArmConfig& cfg, const Grasp& g, const Joints& current, Joints& out, std::string& error) {
  std::vector<IkSolution> sols;
  if (!ik_solutions(cfg, g, current, sols, error)) return false;
  for (const IkSolution& s : sols) {
    if (s.elbow_up && s.limit_error.empty()) {
      out = s.joints;
      return true;
    }
  }
  error = "no elbow-up solution within the joint limits: " + sols.front().limit_error;
  return false;
}

}  // namespace rbx1::arm
