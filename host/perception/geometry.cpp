// geometry.cpp - area moments, sub-pixel outer contour (the edge points) and the sorted r-theta profile.
#include "geometry.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "pixels.hpp"

namespace rbx1::vision {

float sample(const cv::Mat& img, double x, double y) {
  x = std::clamp(x, 0.0, double(img.cols - 1));
  y = std::clamp(y, 0.0, double(img.rows - 1));
  int x0 = std::min(int(x), img.cols - 2 < 0 ? 0 : img.cols - 2), y0 = std::min(int(y), img.rows - 2 < 0 ? 0 : img.rows - 2);
  int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  float fx = float(x - x0), fy = float(y - y0);
  const float* r0 = img.ptr<float>(y0);
  const float* r1 = img.ptr<float>(y1);
  return (r0[x0] * (1 - fx) + r0[x1] * fx) * (1 - fy) + (r1[x0] * (1 - fx) + r1[x1] * fx) * fy;
}

namespace {

// Where the layer crosses its half level along the line p + t n, t in [-2, 2]: searched from p towards the
// half level (n points up the gradient), linear between samples 0.25 px apart.
double half_level_offset(const cv::Mat& s, cv::Point2d p, cv::Point2d n) {
  constexpr int kSteps = 8;
  float a = sample(s, p.x, p.y) - 0.5f;
  if (a == 0) return 0;
  const int dir = a > 0 ? -1 : +1;
  for (int i = 1; i <= kSteps; ++i) {
    double t = dir * 0.25 * i;
    float b = sample(s, p.x + t * n.x, p.y + t * n.y) - 0.5f;
    if ((a < 0) != (b < 0) || b == 0) {
      double t0 = dir * 0.25 * (i - 1);
      return t0 + (t - t0) * (a / (a - b));
    }
    a = b;
  }
  return 0;
}

// The layer summed on a steep ramp about its half level (0 below 1/3, 1 above 2/3): symmetric about 0.5, so an
// anti-aliased or blurred edge still counts at its covered fraction, while the soft layer's own sum also counts
// a cast shadow's or fringe's faint fraction all round the object. That sum depends on the object's grey
// (a light part's shadow is a larger fraction of its contrast: a thin ring measured 8 % larger when light grey
// than when black under the same light); this one does not (1 %), so teaching and picking agree on size.
double half_level_area(const cv::Mat& s) {
  double sum = 0;
  for (int y = 0; y < s.rows; ++y) {
    const float* row = s.ptr<float>(y);
    for (int x = 0; x < s.cols; ++x) sum += std::clamp(3 * row[x] - 1, 0.0f, 1.0f);
  }
  return sum;
}

}  // namespace

bool measure_geometry(const Layer& layer, Geometry& out) {
  const cv::Mat& s = layer.soft;
  cv::Moments m = moments_second_order(s);  // cv::moments(s, false), fused
  if (m.m00 <= 0) return false;
  out.area_px = m.m00;
  out.half_area_px = std::max(half_level_area(s), 1.0);
  out.centroid = {m.m10 / m.m00 + layer.roi.x, m.m01 / m.m00 + layer.roi.y};
  out.mu20 = m.mu20 / m.m00;
  out.mu02 = m.mu02 / m.m00;
  out.mu11 = m.mu11 / m.m00;

  // The paper's edge image (Eq. 1-2): |G| of the layer against t, counted over the object's ROI.
  // (cv::Sobel with 1/8 and the count of gx^2 + gy^2 > t^2, in one pass.)
  cv::Mat gx, gy;
  out.edge_pixels = sobel_gradient(s, gx, gy, float(kEdgeThreshold * kEdgeThreshold));

  const std::vector<cv::Point>& c = layer.outer;
  if (c.empty()) return false;
  out.contour.clear();
  out.psi.clear();
  out.rho.clear();
  out.contour.reserve(c.size());
  for (const cv::Point& p : c) {
    cv::Point2d g(gx.at<float>(p), gy.at<float>(p));
    double mag = std::hypot(g.x, g.y);
    if (mag <= kEdgeThreshold) continue;  // Eq. 2 against t: not an edge pixel
    cv::Point2d n = g / mag;
    double t = half_level_offset(s, cv::Point2d(p), n);
    out.contour.push_back({p.x + t * n.x + layer.roi.x, p.y + t * n.y + layer.roi.y, 1});
  }
  const size_t n = out.contour.size();
  if (n < 3) return false;
  // Each point stands for half of its two neighbouring segments: the scatter becomes a line integral.
  // (Each segment's length once: seg[i] from point i to point i + 1.)
  std::vector<double> seg(n);
  for (size_t i = 0; i < n; ++i) {
    const EdgePoint& b = out.contour[i];
    const EdgePoint& c2 = out.contour[(i + 1) % n];
    seg[i] = std::hypot(c2.x - b.x, c2.y - b.y);
  }
  for (size_t i = 0; i < n; ++i) out.contour[i].w = 0.5 * (seg[(i + n - 1) % n] + seg[i]);
  // Centroid of the region inside the sub-pixel contour (Green's theorem): the contour sits at the object's
  // half level, where a soft shadow or uneven table next to one side barely moves it, whereas the soft
  // layer's edge band would lean towards the shadow. The layer's moments remain the fallback.
  double a2 = 0, cx = 0, cy = 0;
  for (size_t i = 0; i < n; ++i) {
    const EdgePoint& p = out.contour[i];
    const EdgePoint& q = out.contour[(i + 1) % n];
    double cr = p.x * q.y - q.x * p.y;
    a2 += cr, cx += (p.x + q.x) * cr, cy += (p.y + q.y) * cr;
  }
  if (std::abs(a2) / 2 >= 0.5 * out.area_px) out.centroid = {cx / (3 * a2), cy / (3 * a2)};
  // r-theta profile (Eq. 3-4) around the centroid, sorted by angle in [0, 2pi).
  std::vector<std::pair<double, double>> tr(n);
  out.psi.resize(n);
  out.rho.resize(n);
  for (size_t i = 0; i < n; ++i) {
    double dx = out.contour[i].x - out.centroid.x, dy = out.contour[i].y - out.centroid.y;
    double th = out.psi[i] = std::atan2(dy, dx);
    if (th < 0) th += 2 * M_PI;
    tr[i] = {th, out.rho[i] = std::hypot(dx, dy)};
  }
  std::sort(tr.begin(), tr.end());
  out.theta.resize(n);
  out.r.resize(n);
  for (size_t i = 0; i < n; ++i) {
    out.theta[i] = tr[i].first;
    out.r[i] = tr[i].second;
  }
  return true;
}

}  // namespace rbx1::vision
