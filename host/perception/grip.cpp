// grip.cpp - chords through the centroid from the sub-pixel contour, the minimum opening and finger clearance.
#include "grip.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace rbx1::vision {
namespace {

double cross(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

// Whether measure_geometry left the contour's angles and distances about the centroid (the same values).
bool has_polar(const Geometry& g) { return g.psi.size() == g.contour.size() && g.rho.size() == g.contour.size(); }

// cos and sin of the ray angles j * pi / lines for j in [-2 lines, 2 lines] (index j + 2 lines), computed once
// per thread and line count (the same values as computing them per crossing).
struct RayAngles {
  int lines = 0;
  std::vector<double> cos, sin;
};
const RayAngles& ray_angles(int lines) {
  thread_local RayAngles t;
  if (t.lines != lines) {
    const double step = M_PI / lines;
    t.cos.resize(4 * size_t(lines) + 1);
    t.sin.resize(4 * size_t(lines) + 1);
    for (int j = -2 * lines; j <= 2 * lines; ++j) {
      const double psi = j * step;
      t.cos[size_t(j + 2 * lines)] = std::cos(psi);
      t.sin[size_t(j + 2 * lines)] = std::sin(psi);
    }
    t.lines = lines;
  }
  return t;
}

// Line parameters (t) of both contacts from the two opposite rays of line k: the outermost crossing on each
// side of the centroid. false when one side has no crossing (a one-sided chord is no grip: its "opening" can be 0).
bool line_from_rays(const RayHits& h, int k, int lines, double& tmin, double& tmax) {
  double fmax = h.rmax[size_t(k)], bmax = h.rmax[size_t(k + lines)];
  if (fmax <= 0 || bmax <= 0) return false;
  tmax = fmax;
  tmin = -bmax;
  return true;
}

// Does a finger (width across the line, depth outward) at contact q, pushing along -out, sit on another object?
bool finger_blocked(cv::Point2d q, cv::Point2d out, int own, const cv::Mat& labels, const std::vector<uint8_t>& obstacle,
                    const GripOptions& opt) {
  if (opt.finger_width_px <= 0 || opt.finger_depth_px <= 0 || labels.empty()) return false;
  cv::Point2d across(-out.y, out.x);
  const double hw = opt.finger_width_px / 2;
  for (double a = 1; a <= opt.finger_depth_px; a += 1) {
    for (double b = -hw; b <= hw + 1e-9; b += 1) {
      cv::Point2d p = q + a * out + b * across;
      int x = int(std::lround(p.x)), y = int(std::lround(p.y));
      if (x < 0 || y < 0 || x >= labels.cols || y >= labels.rows) continue;
      int l = labels.at<int>(y, x);
      if (l != 0 && l != own && size_t(l) < obstacle.size() && obstacle[size_t(l)]) return true;
    }
  }
  return false;
}

// A crack in the outline narrower than a finger is no way in: when the closing line runs into the outline
// between contour points on both of its sides within kContactHalfWidth (a slit, 1 px wide on coins.png's round17
// where a dark pit sits in the rim: 4.5 px deep, the narrowest line 37.0 px across a coin 41 px wide), the
// contact moves out to where the nearer of the two walls ends. A ray that only grazes a corner, or meets a smooth
// edge (the points beside it lie inside its crossing), keeps its crossing. Per contour point, only the rays
// within asin(h / r) of its direction can hold it.
constexpr double kContactHalfWidth = 1.0;

void close_cracks(const Geometry& g, int lines, const std::vector<char>& valid, std::vector<double>& lo,
                  std::vector<double>& hi) {
  const double step = M_PI / lines, h = kContactHalfWidth;
  const int rays = 2 * lines;
  std::vector<double> left(size_t(rays), -1), right(size_t(rays), -1);  // farthest wall point on each side
  const bool polar = has_polar(g);
  for (size_t i = 0; i < g.contour.size(); ++i) {
    const EdgePoint& p = g.contour[i];
    const double x = p.x - g.centroid.x, y = p.y - g.centroid.y, r = polar ? g.rho[i] : std::hypot(x, y);
    if (r <= 2 * h) continue;  // near the centroid: never a ray's outermost point
    const double psi = polar ? g.psi[i] : std::atan2(y, x), delta = std::asin(h / r);
    const int j0 = int(std::ceil((psi - delta) / step)), j1 = int(std::floor((psi + delta) / step));
    for (int j = j0; j <= j1; ++j) {
      const size_t q = size_t(((j % rays) + rays) % rays);
      const double t = r * std::cos(psi - j * step);
      std::vector<double>& side = psi >= j * step ? left : right;
      side[q] = std::max(side[q], t);
    }
  }
  for (int k = 0; k < lines; ++k) {
    if (!valid[size_t(k)]) continue;
    hi[size_t(k)] = std::max(hi[size_t(k)], std::min(left[size_t(k)], right[size_t(k)]));
    lo[size_t(k)] = std::min(lo[size_t(k)], -std::min(left[size_t(k + lines)], right[size_t(k + lines)]));
  }
}

// Where real fingers come down on each line: outside the object's outermost contour points within their
// width (|across| <= half), not at the line's own crossings, which would put a finger on the object's other
// parts (a star's neighbouring points, an L's other arm). And the planner centres the gripper on the
// centroid, so both fingers open to the farther of the two: the faces are at -H and +H. The contour is
// dense (sub-pixel edge points ~1 px apart), so its points stand for the region.
void widen_to_fingers(const Geometry& g, int lines, double half, const std::vector<char>& valid,
                      std::vector<double>& lo, std::vector<double>& hi) {
  const size_t n = g.contour.size();
  std::vector<double> x(n), y(n);
  for (size_t i = 0; i < n; ++i) x[i] = g.contour[i].x - g.centroid.x, y[i] = g.contour[i].y - g.centroid.y;
  for (int k = 0; k < lines; ++k) {
    if (!valid[size_t(k)]) continue;
    const double phi = k * M_PI / lines, c = std::cos(phi), s = std::sin(phi);
    double a = lo[size_t(k)], b = hi[size_t(k)];
    for (size_t i = 0; i < n; ++i) {
      if (std::abs(c * y[i] - s * x[i]) > half) continue;
      const double t = c * x[i] + s * y[i];
      a = std::min(a, t), b = std::max(b, t);
    }
    const double h = std::max(b, -a);
    lo[size_t(k)] = -h, hi[size_t(k)] = h;
  }
}

Grip make_grip(const Geometry& g, double phi, double tmin, double tmax) {
  Grip gr;
  cv::Point2d u(std::cos(phi), std::sin(phi));
  cv::Point2d a = g.centroid + tmin * u, b = g.centroid + tmax * u;
  double deg = phi * 180 / M_PI;  // [0, 180)
  if (deg <= 90) {
    gr.p1 = a, gr.p2 = b, gr.angle_deg = deg;
  } else {
    gr.p1 = b, gr.p2 = a, gr.angle_deg = deg - 180;
  }
  gr.opening_px = tmax - tmin;
  return gr;
}

}  // namespace

RayHits cast_rays(const Geometry& g, int lines) {
  const int rays = 2 * lines;
  const double step = M_PI / lines;
  RayHits h;
  h.rmax.assign(size_t(rays), -1);
  h.rmin.assign(size_t(rays), -1);
  const auto& c = g.contour;
  const size_t n = c.size();
  const bool polar = has_polar(g);
  const RayAngles& ang = ray_angles(lines);
  for (size_t i = 0; i < n; ++i) {
    double ax = c[i].x - g.centroid.x, ay = c[i].y - g.centroid.y;
    double bx = c[(i + 1) % n].x - g.centroid.x, by = c[(i + 1) % n].y - g.centroid.y;
    double ta = polar ? g.psi[i] : std::atan2(ay, ax);
    double dt = std::remainder((polar ? g.psi[(i + 1) % n] : std::atan2(by, bx)) - ta, 2 * M_PI);
    if (std::abs(dt) > 0.75 * M_PI) continue;  // the segment passes over the centroid itself
    double lo = std::min(ta, ta + dt), hi = std::max(ta, ta + dt);
    double dx = bx - ax, dy = by - ay;
    // Rays through a vertex may be found by both segments (harmless for max/min); widen by a hair so that
    // rounding in atan2 at +-pi never loses one.
    int j0 = int(std::ceil((lo - 1e-9) / step)), j1 = int(std::floor((hi + 1e-9) / step));
    for (int j = j0; j <= j1; ++j) {
      double ux, uy;
      if (j >= -2 * lines && j <= 2 * lines) {
        ux = ang.cos[size_t(j + 2 * lines)], uy = ang.sin[size_t(j + 2 * lines)];
      } else {
        const double psi = j * step;
        ux = std::cos(psi), uy = std::sin(psi);
      }
      double den = cross(ux, uy, dx, dy);
      if (std::abs(den) < 1e-12) continue;
      double sp = cross(ax, ay, ux, uy) / den;
      if (sp < -1e-9 || sp > 1 + 1e-9) continue;
      double r = cross(ax, ay, dx, dy) / den;
      if (r < 0) continue;
      size_t k = size_t(((j % rays) + rays) % rays);
      if (h.rmax[k] < r) h.rmax[k] = r;
      if (h.rmin[k] < 0 || h.rmin[k] > r) h.rmin[k] = r;
    }
  }
  return h;
}

bool chord_at(const Geometry& g, double phi, double& tmin, double& tmax) {
  const double ux = std::cos(phi), uy = std::sin(phi);
  const auto& c = g.contour;
  const size_t n = c.size();
  bool any = false;
  for (size_t i = 0; i < n; ++i) {
    double ax = c[i].x - g.centroid.x, ay = c[i].y - g.centroid.y;
    double dx = c[(i + 1) % n].x - c[i].x, dy = c[(i + 1) % n].y - c[i].y;
    double den = cross(ux, uy, dx, dy);
    if (std::abs(den) < 1e-12) continue;
    double s = cross(ax, ay, ux, uy) / den;
    if (s < -1e-9 || s > 1 + 1e-9) continue;
    double t = cross(ax, ay, dx, dy) / den;
    if (!any) tmin = tmax = t;
    tmin = std::min(tmin, t), tmax = std::max(tmax, t);
    any = true;
  }
  return any;
}

const char* grip_reason_name(GripReason r) {
  switch (r) {
    case GripReason::TooWide: return "too_wide";
    case GripReason::TooNarrow: return "too_narrow";
    case GripReason::NoContact: return "no_contact";
    case GripReason::FingerCollision: return "finger_collision";
    case GripReason::None: break;
  }
  return nullptr;
}

Grip choose_grip(const Geometry& g, const RayHits& hits, int own_label, const cv::Mat& labels,
                 const std::vector<uint8_t>& obstacle, const GripOptions& opt, std::vector<double>& phi,
                 std::vector<double>& d) {
  const int lines = opt.lines;
  const double step = M_PI / lines;
  phi.clear(), d.clear();
  std::vector<double> lo(static_cast<size_t>(lines)), hi(static_cast<size_t>(lines));
  std::vector<char> valid(static_cast<size_t>(lines), 0);
  for (int k = 0; k < lines; ++k) {
    double tmin = 0, tmax = 0;
    if (!line_from_rays(hits, k, lines, tmin, tmax)) continue;
    lo[size_t(k)] = tmin, hi[size_t(k)] = tmax, valid[size_t(k)] = 1;
  }
  close_cracks(g, lines, valid, lo, hi);
  if (opt.finger_width_px > 0 && opt.finger_depth_px > 0) widen_to_fingers(g, lines, opt.finger_width_px / 2, valid, lo, hi);
  for (int k = 0; k < lines; ++k) {
    if (!valid[size_t(k)]) continue;
    phi.push_back(k * step);
    d.push_back(hi[size_t(k)] - lo[size_t(k)]);
  }
  Grip none;
  none.feasible = false, none.reason = GripReason::NoContact;
  none.p1 = none.p2 = g.centroid;
  if (phi.empty()) return none;
  // D is flat near its minimum (quadratic for parallel sides) and the sub-pixel contour carries ~0.1 px of
  // noise, so the raw argmin wanders over the flat part. Rank lines by D averaged over +-3 degrees instead:
  // symmetric minima stay put, and the opening reported is still the exact chord on the chosen line.
  const int w = std::max(1, int(std::lround(3.0 / (180.0 / lines))));
  std::vector<double> smooth(static_cast<size_t>(lines), 1e300);
  std::vector<int> order;
  for (int k = 0; k < lines; ++k) {
    if (!valid[size_t(k)]) continue;
    double acc = 0;
    int n = 0;
    for (int j = k - w; j <= k + w; ++j) {
      // Line k + lines is line k reversed: the same chord (w <= lines, so one wrap at most).
      const int q = j < 0 ? j + lines : j >= lines ? j - lines : j;
      if (valid[size_t(q)]) acc += hi[size_t(q)] - lo[size_t(q)], ++n;
    }
    smooth[size_t(k)] = acc / n;
    order.push_back(k);
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return smooth[size_t(a)] < smooth[size_t(b)]; });

  auto open = [&](int k) { return hi[size_t(k)] - lo[size_t(k)]; };
  auto in_range = [&](int k) {
    return open(k) >= std::max(opt.min_opening_px, 1e-6) && (opt.max_opening_px <= 0 || open(k) <= opt.max_opening_px);
  };
  auto clear_at = [&](double ph, double tmin, double tmax) {
    cv::Point2d u(std::cos(ph), std::sin(ph));
    return !finger_blocked(g.centroid + tmax * u, u, own_label, labels, obstacle, opt) &&
           !finger_blocked(g.centroid + tmin * u, -u, own_label, labels, obstacle, opt);
  };
  int best = -1, first_in_range = -1;
  for (int k : order) {
    if (!in_range(k)) continue;
    if (first_in_range < 0) first_in_range = k;
    if (clear_at(k * step, lo[size_t(k)], hi[size_t(k)])) {
      best = k;
      break;
    }
  }
  GripReason reason = GripReason::None;
  int shown = best;
  if (best < 0 && first_in_range >= 0) {
    reason = GripReason::FingerCollision;
    shown = first_in_range;
  } else if (best < 0) {
    // Nothing in range: the narrowest real chord tells which way it misses.
    shown = order.front();
    reason = open(shown) < opt.min_opening_px ? GripReason::TooNarrow : GripReason::TooWide;
  }
  Grip out = make_grip(g, shown * step, lo[size_t(shown)], hi[size_t(shown)]);
  out.clear = reason != GripReason::FingerCollision;
  out.reason = reason;
  out.feasible = reason == GripReason::None;
  return out;
}

}  // namespace rbx1::vision
