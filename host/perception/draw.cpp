// draw.cpp - annotated frame and r-theta / D(theta) plots with OpenCV drawing.
#include "draw.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

constexpr int kShift = 4;  // fixed-point bits for sub-pixel drawing
cv::Point fx(cv::Point2d p) { return {int(std::lround(p.x * (1 << kShift))), int(std::lround(p.y * (1 << kShift)))}; }

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

bool inside_layer(const Layer& l, cv::Point2d p) {
  cv::Point q(int(std::lround(p.x)) - l.roi.x, int(std::lround(p.y)) - l.roi.y);
  return q.x >= 0 && q.y >= 0 && q.x < l.inside.cols && q.y < l.inside.rows && l.inside.at<uchar>(q) != 0;
}

}  // namespace

cv::Point2d label_anchor(const DetectedObject& o) {
  const cv::Point2d c = o.geometry.centroid;
  double len = 0;
  for (double r : o.geometry.r) len = std::max(len, r);
  const double a = o.pose.orientation_deg * M_PI / 180;
  const cv::Point2d u(std::cos(a), std::sin(a));
  // Half-way out along the axis (off the centroid mark and the grip line), on whichever side is inside.
  for (double f : {0.5, -0.5, 0.3, -0.3, 0.0})
    if (inside_layer(o.layer, c + f * len * u)) return c + f * len * u;
  // A centroid outside the object (a U, a ring): its deepest pixel.
  if (o.layer.inside.empty()) return c;
  cv::Mat dist;
  cv::distanceTransform(o.layer.inside, dist, cv::DIST_L2, 3);
  cv::Point best;
  cv::minMaxLoc(dist, nullptr, nullptr, nullptr, &best);
  return cv::Point2d(best + o.layer.roi.tl());
}

cv::Mat annotate(const cv::Mat& frame, const Detection& det, bool calibrated) {
  cv::Mat img;
  if (frame.channels() == 1) cv::cvtColor(frame, img, cv::COLOR_GRAY2BGR);
  else if (frame.channels() == 4) cv::cvtColor(frame, img, cv::COLOR_BGRA2BGR);
  else img = frame.clone();
  if (img.depth() != CV_8U) img.convertTo(img, CV_8U, img.depth() == CV_16U ? 1.0 / 257 : 1.0);
  const double font = std::max(0.4, img.cols / 1600.0);
  const int thick = std::max(1, img.cols / 800);
  for (const DetectedObject& o : det.objects) {
    std::vector<cv::Point> poly;
    for (const EdgePoint& e : o.geometry.contour) poly.push_back(fx({e.x, e.y}));
    cv::polylines(img, poly, true, cv::Scalar(0, 200, 0), thick, cv::LINE_AA, kShift);
    // Principal axis through the centroid, as long as the object.
    double len = 0;
    for (double r : o.geometry.r) len = std::max(len, r);
    double a = o.pose.orientation_deg * M_PI / 180;
    cv::Point2d u(std::cos(a), std::sin(a)), c = o.geometry.centroid;
    cv::line(img, fx(c - (len + 6) * u), fx(c + (len + 6) * u), cv::Scalar(255, 120, 0), thick, cv::LINE_AA, kShift);
    cv::circle(img, fx(c), 3 << kShift, cv::Scalar(255, 120, 0), -1, cv::LINE_AA, kShift);
    // Grip: the two contacts and the opening between them.
    cv::Scalar gc = o.grip.feasible ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 140, 255);
    cv::line(img, fx(o.grip.p1), fx(o.grip.p2), gc, thick, cv::LINE_AA, kShift);
    cv::circle(img, fx(o.grip.p1), 4 << kShift, gc, -1, cv::LINE_AA, kShift);
    cv::circle(img, fx(o.grip.p2), 4 << kShift, gc, -1, cv::LINE_AA, kShift);
    // The number sits on its own object (centred on label_anchor), never beside a neighbour.
    std::string num = "#" + std::to_string(o.index) + (o.identity.label ? " " + *o.identity.label : "");
    int base = 0;
    cv::Size ts = cv::getTextSize(num, cv::FONT_HERSHEY_SIMPLEX, font, thick + 2, &base);
    cv::Point2d an = label_anchor(o);
    cv::Point tp(int(an.x - ts.width / 2.0), int(an.y + ts.height / 2.0));
    tp.x = std::clamp(tp.x, 0, std::max(0, img.cols - ts.width));
    tp.y = std::clamp(tp.y, ts.height, img.rows - 2);
    cv::putText(img, num, tp, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), thick + 2, cv::LINE_AA);
    cv::putText(img, num, tp, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
    std::string open = o.grip.opening_cm ? fmt("%.2f cm", *o.grip.opening_cm) : fmt("%.1f px", o.grip.opening_px);
    cv::Point op(int(o.grip.p2.x + 6), int(o.grip.p2.y + 4));
    op.x = std::clamp(op.x, 0, std::max(0, img.cols - 70));
    op.y = std::clamp(op.y, 14, img.rows - 2);
    cv::putText(img, open, op, cv::FONT_HERSHEY_SIMPLEX, font * 0.8, gc, thick, cv::LINE_AA);
  }
  (void)calibrated;
  return img;
}

cv::Mat plot_xy(const std::vector<double>& x, const std::vector<double>& y, const std::string& title,
                const std::string& xlabel, const std::string& ylabel, bool points) {
  const int W = 720, H = 420, L = 70, R = 20, T = 40, B = 50;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  if (x.empty() || x.size() != y.size()) return img;
  double x0 = *std::min_element(x.begin(), x.end()), x1 = *std::max_element(x.begin(), x.end());
  double y0 = 0, y1 = *std::max_element(y.begin(), y.end()) * 1.1;
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) y1 = y0 + 1;
  auto map = [&](double xv, double yv) {
    return cv::Point2d(L + (xv - x0) / (x1 - x0) * (W - L - R), H - B - (yv - y0) / (y1 - y0) * (H - T - B));
  };
  cv::Scalar axis(0, 0, 0), grid(220, 220, 220);
  for (int i = 0; i <= 4; ++i) {
    double xv = x0 + (x1 - x0) * i / 4, yv = y0 + (y1 - y0) * i / 4;
    cv::line(img, map(xv, y0), map(xv, y1), grid);
    cv::line(img, map(x0, yv), map(x1, yv), grid);
    cv::putText(img, fmt("%.0f", xv), map(xv, y0) + cv::Point2d(-12, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, axis, 1, cv::LINE_AA);
    cv::putText(img, fmt("%.1f", yv), map(x0, yv) + cv::Point2d(-55, 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, axis, 1, cv::LINE_AA);
  }
  cv::rectangle(img, map(x0, y1), map(x1, y0), axis);
  std::vector<cv::Point> poly;
  for (size_t i = 0; i < x.size(); ++i) poly.push_back(fx(map(x[i], y[i])));
  if (points) {
    for (const cv::Point& p : poly) cv::circle(img, p, 1 << kShift, cv::Scalar(200, 60, 0), -1, cv::LINE_AA, kShift);
  } else {
    cv::polylines(img, poly, false, cv::Scalar(200, 60, 0), 2, cv::LINE_AA, kShift);
  }
  cv::putText(img, title, {L, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.6, axis, 1, cv::LINE_AA);
  cv::putText(img, xlabel, {W / 2 - 40, H - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.5, axis, 1, cv::LINE_AA);
  cv::putText(img, ylabel, {5, T - 10}, cv::FONT_HERSHEY_SIMPLEX, 0.5, axis, 1, cv::LINE_AA);
  return img;
}

bool write_plots(const DetectedObject& o, const std::string& dir, std::string& error) {
  const std::string base = dir + "/object-" + std::to_string(o.index);
  const Geometry& g = o.geometry;
  std::vector<double> deg(g.theta.size()), ref_deg, ref_r;
  for (size_t i = 0; i < g.theta.size(); ++i) deg[i] = g.theta[i] * 180 / M_PI;
  // The edge points rotated to the reference orientation (axis along x) and sorted again (Figs. 13, 16, 17).
  std::vector<std::pair<double, double>> ref;
  for (size_t i = 0; i < g.theta.size(); ++i) {
    double t = std::fmod(deg[i] - o.pose.orientation_deg + 720, 360.0);
    ref.emplace_back(t, g.r[i]);
  }
  std::sort(ref.begin(), ref.end());
  for (auto& [t, r] : ref) ref_deg.push_back(t), ref_r.push_back(r);
  std::vector<double> dphi(o.chord_phi.size());
  for (size_t i = 0; i < dphi.size(); ++i) dphi[i] = o.chord_phi[i] * 180 / M_PI;
  struct Out { std::string file; cv::Mat img; };
  std::string n = "object #" + std::to_string(o.index);
  Out outs[] = {
      {base + "-profile.png", plot_xy(deg, g.r, "r-theta profile, " + n, "theta (deg)", "r (px)", true)},
      {base + "-profile-ref.png",
       plot_xy(ref_deg, ref_r, "r-theta at the reference orientation, " + n, "theta from axis (deg)", "r (px)", true)},
      {base + "-opening.png", plot_xy(dphi, o.chord_d, "D(theta) = r(theta) + r(theta+pi), " + n, "theta (deg)", "D (px)")},
  };
  for (const Out& out : outs) {
    bool ok = false;
    try {
      ok = cv::imwrite(out.file, out.img);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (!ok) {
      error = out.file + ": cannot write";
      return false;
    }
  }
  return true;
}

}  // namespace rbx1::vision
