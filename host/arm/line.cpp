// line.cpp - straight-line segmentation: IK at the ends of each segment, halving where the joint-linear path
// between them leaves the bounds (sampled with FK) or where the firmware's junction rule would slow the line below
// its curvature's limit.
#include "line.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "joint_steps.hpp"
#include "line_timing.hpp"

namespace rbx1::arm {

namespace {

constexpr int kSamples = 16;  // FK samples per segment while planning (the tests sample more densely)
constexpr int kMaxDepth = 14; // at most 2^14 segments per line
// Segments this short (dominant steps) are not halved for their junction: rounding to steps alone turns a joint's
// share of the dominant steps by up to 1/n.
constexpr int64_t kMinJunctionSteps = 40;

Grasp lerp(const Grasp& a, const Grasp& b, double t) {
  double dyaw = normalize_axis_deg(b.yaw_deg - a.yaw_deg);
  return Grasp{a.x_mm + t * (b.x_mm - a.x_mm), a.y_mm + t * (b.y_mm - a.y_mm), a.z_mm + t * (b.z_mm - a.z_mm),
               normalize_axis_deg(a.yaw_deg + t * dyaw)};
}

Joints lerp_joints(const Joints& a, const Joints& b, double t) {
  Joints q{};
  for (int j = 0; j < kJoints; ++j) q[j] = a[j] + t * (b[j] - a[j]);
  return q;
}

std::string point(const Grasp& g) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.1f, %.1f, %.1f) mm", g.x_mm, g.y_mm, g.z_mm);
  return buf;
}

struct Planner {
  const ArmConfig& cfg;
  const Grasp &from, &to;
  const LineBounds& bounds;
  std::vector<Steps>& out;
  std::vector<double>& ts;  // the line parameter of each target in out
  std::string& error;

  bool within(const Steps& a, const Steps& b) const {
    LineError e = line_error(cfg, a, b, from, to, kSamples);
    return e.deviation_mm <= bounds.deviation_mm && e.yaw_deg <= bounds.yaw_deg && e.tilt_deg <= bounds.tilt_deg;
  }

  // Appends the targets after `a` (at t0) up to t1, whose target is b.
  bool split(const Steps& a, double t0, const Steps& b, double t1, int depth) {
    if (within(a, b)) {
      out.push_back(b);
      ts.push_back(t1);
      return true;
    }
    if (depth >= kMaxDepth) {
      error = "no split of the line near " + point(lerp(from, to, t0)) + " stays within " +
              std::to_string(bounds.deviation_mm) + " mm";
      return false;
    }
    return halve(a, t0, b, t1, depth + 1);
  }

  // Splits a -> b at the middle of the line between t0 and t1 and appends both halves' targets.
  bool halve(const Steps& a, double t0, const Steps& b, double t1, int depth) {
    double tm = 0.5 * (t0 + t1);
    Grasp g = lerp(from, to, tm);
    Joints q{};
    std::string why;
    // The solution nearest the straight joint path between the ends keeps the branch (elbow, wrist) of the line.
    if (!ik(cfg, g, lerp_joints(steps_to_joints(cfg, a), steps_to_joints(cfg, b), 0.5), q, why)) {
      error = "the line leaves the workspace at " + point(g) + ": " + why;
      return false;
    }
    Steps m = joints_to_steps(cfg, q);
    return split(a, t0, m, tm, depth) && split(m, tm, b, t1, depth);
  }
};

int64_t dominant_steps(const Steps& a, const Steps& b) {
  int64_t n = 0;
  for (int j = 0; j < kJoints; ++j) n = std::max<int64_t>(n, std::llabs(int64_t(b[j]) - a[j]));
  return n;
}

}  // namespace

LineError line_error(const ArmConfig& cfg, const Steps& a, const Steps& b, const Grasp& from, const Grasp& to,
                     int samples) {
  const Eigen::Vector3d p0(from.x_mm, from.y_mm, from.z_mm), p1(to.x_mm, to.y_mm, to.z_mm);
  const Eigen::Vector3d d = p1 - p0;
  const double len2 = d.squaredNorm();
  const Joints qa = steps_to_joints(cfg, a), qb = steps_to_joints(cfg, b);
  LineError e;
  for (int k = 0; k < samples; ++k) {
    double s = samples > 1 ? double(k) / (samples - 1) : 0.0;
    ToolPose tp = tool_pose(cfg.links, lerp_joints(qa, qb, s));
    Eigen::Vector3d p(tp.x_mm, tp.y_mm, tp.z_mm);
    double t = len2 > 0 ? std::clamp((p - p0).dot(d) / len2, 0.0, 1.0) : 0.0;
    e.deviation_mm = std::max(e.deviation_mm, (p - (p0 + t * d)).norm());
    e.yaw_deg = std::max(e.yaw_deg, std::fabs(normalize_axis_deg(tp.yaw_deg - lerp(from, to, t).yaw_deg)));
    e.tilt_deg = std::max(e.tilt_deg, tp.tilt_deg);
  }
  return e;
}

bool plan_line(const ArmConfig& cfg, const Steps& start, const Grasp& from, const Grasp& to, const LineBounds& bounds,
               std::vector<Steps>& out, std::string& error) {
  out.clear();
  Joints q{};
  std::string why;
  if (!ik(cfg, to, steps_to_joints(cfg, start), q, why)) {
    error = "the line's end " + point(to) + " is out of reach: " + why;
    return false;
  }
  std::vector<double> ts;
  Planner p{cfg, from, to, bounds, out, ts, error};
  if (!p.split(start, 0.0, joints_to_steps(cfg, q), 1.0, 0)) return false;
  // Junctions where a joint's velocity jump (the firmware's lag rule) limits the rate below what the curvature
  // (its curve rule) and both segments' cruise allow: both segments are halved, which halves the jump at the same
  // rate while the curve limit stays, until the jump no longer binds, a segment is under kMinJunctionSteps or
  // halving no longer shortens the line.
  // A pass that does not shorten the line's time at the limits (the firmware's model) is undone.
  auto fastest = [&] { return stream_seconds(cfg, start, out, std::vector<double>(out.size(), 1e30)); };
  double best = fastest();
  for (int pass = 0; pass < kMaxDepth; ++pass) {
    std::vector<bool> halve(out.size(), false);
    bool any = false;
    for (size_t k = 0; k + 1 < out.size(); ++k) {
      const Steps& a = k ? out[k - 1] : start;
      const JunctionLimits j = junction_limits(cfg, a, out[k], out[k + 1]);
      if (j.jump >= std::min(j.curve, j.cruise)) continue;
      if (dominant_steps(a, out[k]) >= 2 * kMinJunctionSteps) halve[k] = any = true;
      if (dominant_steps(out[k], out[k + 1]) >= 2 * kMinJunctionSteps) halve[k + 1] = any = true;
    }
    if (!any) break;
    std::vector<Steps> segs;
    std::vector<double> segts;
    segs.swap(out);
    segts.swap(ts);
    Steps a = start;
    double t0 = 0.0;
    for (size_t k = 0; k < segs.size(); ++k) {
      if (!halve[k]) {
        out.push_back(segs[k]);
        ts.push_back(segts[k]);
      } else if (!p.halve(a, t0, segs[k], segts[k], 0)) {
        return false;
      }
      a = segs[k];
      t0 = segts[k];
    }
    const double t = fastest();
    if (t >= best) {
      out.swap(segs);
      break;
    }
    best = t;
  }
  return true;
}

}  // namespace rbx1::arm
