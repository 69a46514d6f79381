// line_timing.cpp - a straight line's segment durations from the firmware's look-ahead model (planner.cpp's rules
// in floating point: dominant-joint limits, junction rule, backward and forward passes over v^2).
#include "line_timing.hpp"

#include <algorithm>
#include <cmath>

#include "joint_steps.hpp"

namespace rbx1::arm {

namespace {

constexpr double kJunctionLagSteps = 4;  // firmware/rbx1/src/config.h JUNCTION_LAG_STEPS
constexpr double kStepTimerHz = 2e6;     // config.h STEP_TIMER_HZ: a cruise interval is a whole number of ticks
constexpr double kProfileTickHz = 1000;  // config.h PROFILE_TICK_HZ: a joined move lasts at least two ticks

// One segment as the firmware plans it (planner.cpp plan_move), v being its dominant joint's rate.
struct Seg {
  double d[kJoints] = {};  // signed steps per joint
  double n = 0;            // the dominant joint's steps
  double vmax = 0, a = 0;  // the fastest rate and acceleration every joint's limits allow
  double vc = 0;           // cruise when joined: min(vmax, cap, two profile ticks)
  double v0 = 0;           // stop rate: the first step's rate from rest
  bool stretched = false;  // the cap slows its rest-to-rest profile: joins only at its whole cruise
  double vstretch = 0;     // that profile's cruise
  double bend = 0;         // entered at v, the ramps accelerate at a - bend v^2 (planner.h bend8)
};

std::vector<Seg> segments(const ArmConfig& cfg, const Steps& start, const std::vector<Steps>& targets) {
  std::vector<Seg> out(targets.size());
  Steps at = start;
  for (size_t k = 0; k < targets.size(); ++k) {
    Seg& s = out[k];
    for (int j = 0; j < kJoints; ++j) {
      s.d[j] = double(int64_t(targets[k][j]) - at[j]);
      s.n = std::max(s.n, std::fabs(s.d[j]));
    }
    s.vmax = s.a = 1e30;
    for (int j = 0; j < kJoints; ++j) {
      if (s.d[j] == 0) continue;
      const double r = s.n / std::fabs(s.d[j]);
      s.vmax = std::min(s.vmax, cfg.joints[j].max_speed_steps_s * r);
      s.a = std::min(s.a, cfg.joints[j].accel_steps_s2 * r);
    }
    at = targets[k];
  }
  return out;
}

// The curve bound leaves at least this share of a move's ramp acceleration to its ramps (planner.cpp kRampShare).
constexpr double kRampShare = 0.25;

// The bend's share of joint j's ACCEL at a junction passed at v^2 (per v^2: d_j / min(n, n')).
double bend(const Seg& p, const Seg& b, int j) {
  return std::fabs(p.d[j] / p.n - b.d[j] / b.n) / std::min(p.n, b.n);
}

// planner.cpp's junction(): the largest v^2 at which b may enter after p, or -1 when they do not join; when they
// join, b's bend share (its ramps' acceleration falls by bend * v^2 from a when it enters at v, the chord of the
// joints' limits up to the junction limit).
double junction_sq(const ArmConfig& cfg, const Seg& p, Seg& b) {
  if (p.n == 0 || b.n == 0 || p.vc < p.v0 || b.vc < b.v0) return -1;
  double vj = std::min(p.vc, b.vc), vstart = vj;
  for (int j = 0; j < kJoints; ++j) {
    const double d = std::fabs(p.d[j] / p.n - b.d[j] / b.n);
    if (d * vj <= 0) continue;
    const double acc = cfg.joints[j].accel_steps_s2, w = std::fabs(b.d[j]) / b.n;
    vj = std::min({vj, std::sqrt(2 * acc * kJunctionLagSteps) / d,
                   std::sqrt((acc - w * kRampShare * b.a) / bend(p, b, j))});
    vstart = std::min(vstart, std::sqrt(acc / 2) / d);
  }
  if (b.stretched && vj < 0.999 * b.vstretch) return -1;
  const double floor = std::max(p.v0 * p.v0, b.v0 * b.v0);
  if (vstart * vstart < floor || vj * vj < floor || b.v0 * b.v0 + 2 * b.a * b.n < floor ||
      p.v0 * p.v0 + 2 * p.a * p.n < floor)
    return -1;
  double a = b.a;
  for (int j = 0; j < kJoints; ++j)
    if (b.d[j] != 0)
      a = std::min(a, (cfg.joints[j].accel_steps_s2 - vj * vj * bend(p, b, j)) * b.n / std::fabs(b.d[j]));
  b.bend = (b.a - a) / (vj * vj);
  return vj * vj;
}

// Time over n steps entering at ve^2, leaving at vx^2, ramps at a, cruise at most vc.
double seg_seconds(double n, double ve2, double vx2, double vc, double a) {
  const double vp2 = std::min(vc * vc, 0.5 * (ve2 + vx2) + a * n);
  const double vp = std::sqrt(vp2), ve = std::sqrt(ve2), vx = std::sqrt(vx2);
  const double cruise = std::max(0.0, n - (2 * vp2 - ve2 - vx2) / (2 * a));
  return (vp - ve) / a + (vp - vx) / a + cruise / vp;
}

// The cruise cap the firmware takes from duration_ms (the interval rounded up to whole timer ticks).
double cap_of_ms(double n, uint16_t ms) { return kStepTimerHz / std::ceil(kStepTimerHz * ms * 1e-3 / n - 1e-9); }

}  // namespace

JunctionLimits junction_limits(const ArmConfig& cfg, const Steps& a, const Steps& b, const Steps& c) {
  const std::vector<Seg> s = segments(cfg, a, {b, c});
  JunctionLimits out;
  out.jump = out.curve = 1e30;
  out.cruise = std::min(s[0].vmax, s[1].vmax);
  if (s[0].n == 0 || s[1].n == 0) return out;
  for (int j = 0; j < kJoints; ++j) {
    const double d = std::fabs(s[0].d[j] / s[0].n - s[1].d[j] / s[1].n), acc = cfg.joints[j].accel_steps_s2;
    if (d <= 0) continue;
    out.jump = std::min(out.jump, std::sqrt(2 * acc * kJunctionLagSteps) / d);
    const double w = std::fabs(s[1].d[j]) / s[1].n;
    out.curve = std::min(out.curve, std::sqrt((acc - w * kRampShare * s[1].a) / bend(s[0], s[1], j)));
  }
  return out;
}

double stream_seconds(const ArmConfig& cfg, const Steps& start, const std::vector<Steps>& targets,
                      const std::vector<double>& cap_steps_s) {
  std::vector<Seg> s = segments(cfg, start, targets);
  const size_t c = s.size();
  for (size_t k = 0; k < c; ++k) {
    Seg& g = s[k];
    if (g.n == 0) continue;
    g.vc = std::min({g.vmax, cap_steps_s[k], g.n * kProfileTickHz * 0.5});
    // Rest to rest: the fastest trapezoid, slowed to last n / cap (planner.cpp stretch_v).
    const double fast = std::min(g.vmax, std::sqrt(g.a * g.n)), T = g.n / cap_steps_s[k];
    g.vstretch = fast;
    if (g.n / fast + fast / g.a < T) {
      const double disc = g.a * g.a * T * T - 4 * g.a * g.n;
      const double v = 0.5 * (g.a * T - std::sqrt(std::max(0.0, disc)));
      if (v < fast) g.vstretch = v, g.stretched = true;
    }
    g.v0 = std::min(std::sqrt(g.a / 2), g.vstretch);
  }
  // Junction limits (v^2; -1: a stop), then the backward and forward passes as planner_recalculate() runs them.
  std::vector<double> join(c, -1), entry(c, 0), exit(c, 0);
  for (size_t k = 1; k < c; ++k) join[k] = junction_sq(cfg, s[k - 1], s[k]);
  for (size_t k = 0; k < c; ++k) exit[k] = s[k].v0 * s[k].v0;
  for (size_t k = c; k-- > 1;) {
    if (join[k] < 0) continue;
    const double e = std::min(join[k], (exit[k] + 2 * s[k].a * s[k].n) / (1 + 2 * s[k].bend * s[k].n));
    exit[k - 1] = e;
  }
  double t = 0;
  for (size_t k = 0; k < c; ++k) {
    const Seg& g = s[k];
    entry[k] = k > 0 && join[k] >= 0 ? exit[k - 1] : g.v0 * g.v0;
    const double a = g.a - g.bend * entry[k];
    exit[k] = std::min(exit[k], entry[k] + 2 * a * g.n);
    if (g.n > 0) t += seg_seconds(g.n, entry[k], exit[k], g.vc, a);
  }
  return t;
}

bool time_line(const ArmConfig& cfg, const Steps& start, const std::vector<Steps>& targets, LineTiming& out,
               std::string& error) {
  out = LineTiming{};
  const std::vector<Seg> s = segments(cfg, start, targets);
  std::vector<double> vmax(s.size());
  double travel[kJoints] = {};
  for (size_t k = 0; k < s.size(); ++k) {
    vmax[k] = s[k].vmax;
    for (int j = 0; j < kJoints; ++j) travel[j] += std::fabs(s[k].d[j]) * 360.0 / steps_per_rev(cfg.joints[j]);
  }
  out.pace_s = cfg.speeds.min_move_ms * 1e-3;
  for (int j = 0; j < kJoints; ++j) out.pace_s = std::max(out.pace_s, travel[j] / cfg.speeds.joint_speed_deg_s);
  out.fastest_s = stream_seconds(cfg, start, targets, vmax);
  // One factor on every cruise cap: the largest that keeps the line within the pace (time falls as it rises).
  auto scaled = [&](double f) {
    std::vector<double> v(vmax);
    for (double& x : v) x *= f;
    return v;
  };
  double f = 1;
  if (out.fastest_s < out.pace_s) {
    double lo = 0.5, hi = 1;
    for (int i = 0; i < 60 && stream_seconds(cfg, start, targets, scaled(lo)) < out.pace_s; ++i) hi = lo, lo *= 0.5;
    for (int i = 0; i < 40; ++i) {
      const double mid = 0.5 * (lo + hi);
      (stream_seconds(cfg, start, targets, scaled(mid)) < out.pace_s ? hi : lo) = mid;
    }
    f = lo;
  }
  // At the limits each duration is rounded down (the cap stays at or above the limit: the limit rules); slowed,
  // the running sum is rounded (the caps are right on average and the line keeps its time).
  double sum = 0;
  int64_t sent = 0;
  std::vector<double> caps(s.size());
  for (size_t k = 0; k < s.size(); ++k) {
    int64_t ms = 0;
    if (s[k].n > 0) {
      const double exact = 1000.0 * s[k].n / (f * vmax[k]);
      sum += exact;
      ms = f >= 1 ? int64_t(std::floor(exact + 1e-9)) : std::llround(sum) - sent;
      ms = std::max<int64_t>(ms, 1);
    }
    if (ms > 65535) {
      error = "a segment would take " + std::to_string(ms) + " ms, more than MOVE allows (65535)";
      return false;
    }
    sent += ms;
    out.duration_ms.push_back(uint16_t(ms));
    caps[k] = s[k].n > 0 ? cap_of_ms(s[k].n, uint16_t(ms)) : 0;
  }
  out.planned_s = stream_seconds(cfg, start, targets, caps);
  return true;
}

}  // namespace rbx1::arm
