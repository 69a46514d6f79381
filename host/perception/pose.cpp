// pose.cpp - eigenvector line fitting (Eq. 5-8) with Eigen, and the stable orientation of near-isotropic objects.
#include "pose.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

namespace rbx1::vision {

double fold_axis_deg(double deg) {
  deg = std::fmod(deg, 180.0);
  if (deg <= -90) deg += 180;
  if (deg > 90) deg -= 180;
  return deg;
}

void principal_axis(double a, double b, double c, double& axis_deg, double& ratio) {
  Eigen::Matrix2d s;
  s << a, b, b, c;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(s);
  // Eigenvalues ascend: the principal eigenvector (largest eigenvalue) is column 1.
  Eigen::Vector2d v = es.eigenvectors().col(1);
  axis_deg = fold_axis_deg(std::atan2(v.y(), v.x()) * 180 / M_PI);
  double l1 = std::max(es.eigenvalues()(1), 0.0), l2 = std::max(es.eigenvalues()(0), 1e-12);
  ratio = std::sqrt(l1 / l2);
}

Pose estimate_pose(const Geometry& g, const PoseOptions& opt) {
  Pose p;
  double area_axis = 0, area_ratio = 1;
  principal_axis(g.mu20, g.mu11, g.mu02, area_axis, area_ratio);
  p.elongation = area_ratio;
  p.elongated = area_ratio >= opt.elongated_min;

  double axis = area_axis;
  if (opt.source == AxisSource::Edges) {
    // Scatter matrix S of the centred edge points (Eq. 8), each weighted by the contour length it stands for.
    double sw = 0, mx = 0, my = 0;
    for (const EdgePoint& e : g.contour) sw += e.w, mx += e.w * e.x, my += e.w * e.y;
    mx /= sw, my /= sw;
    double sxx = 0, sxy = 0, syy = 0;
    for (const EdgePoint& e : g.contour) {
      double dx = e.x - mx, dy = e.y - my;
      sxx += e.w * dx * dx, sxy += e.w * dx * dy, syy += e.w * dy * dy;
    }
    double ratio = 1;
    principal_axis(sxx, sxy, syy, axis, ratio);
  }

  if (!p.elongated) {
    // Near-isotropic: the eigenvector is noise. Round objects get 0; others the side of their minimum-area
    // rectangle nearest the x axis, which is repeatable for squares and regular polygons.
    double rmin = 1e300, rmax = 0;
    std::vector<cv::Point2f> pts;
    pts.reserve(g.contour.size());
    for (const EdgePoint& e : g.contour) {
      double r = std::hypot(e.x - g.centroid.x, e.y - g.centroid.y);
      rmin = std::min(rmin, r), rmax = std::max(rmax, r);
      pts.emplace_back(float(e.x), float(e.y));
    }
    if (rmax <= opt.round_max * rmin) {
      axis = 0;
    } else {
      cv::RotatedRect rr = cv::minAreaRect(pts);
      double a = fold_axis_deg(rr.angle);
      if (a > 45) a -= 90;
      if (a <= -45) a += 90;
      axis = a;
    }
  }
  p.orientation_deg = axis;
  double rad = axis * M_PI / 180;
  if (std::abs(std::cos(rad)) > 1e-9) {
    p.slope = std::tan(rad);
    p.intercept = g.centroid.y - *p.slope * g.centroid.x;
  }
  return p;
}

}  // namespace rbx1::vision
