// shapes.cpp - polygon builders, exact ground truth and the supersampled renderer for the tests.
#include "shapes.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace rbx1::vision::test {
namespace {

Poly place(const std::vector<cv::Point2d>& local, cv::Point2d c, double angle_deg) {
  double a = angle_deg * M_PI / 180, ca = std::cos(a), sa = std::sin(a);
  Poly out;
  for (const auto& p : local) out.emplace_back(c.x + p.x * ca - p.y * sa, c.y + p.x * sa + p.y * ca);
  return out;
}

}  // namespace

Poly rectangle(cv::Point2d c, double l, double w, double angle) {
  return place({{-l / 2, -w / 2}, {l / 2, -w / 2}, {l / 2, w / 2}, {-l / 2, w / 2}}, c, angle);
}

Poly ellipse(cv::Point2d c, double a, double b, double angle, int n) {
  std::vector<cv::Point2d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(a * std::cos(2 * M_PI * i / n), b * std::sin(2 * M_PI * i / n));
  return place(pts, c, angle);
}

Poly l_shape(cv::Point2d c, double s, double arm, double angle, bool mirror) {
  std::vector<cv::Point2d> pts = {{0, 0}, {s, 0}, {s, arm}, {arm, arm}, {arm, s * 0.6}, {0, s * 0.6}};
  cv::Point2d m(0, 0);
  for (auto& p : pts) m += p;
  m *= 1.0 / pts.size();
  for (auto& p : pts) {
    p -= m;
    if (mirror) p.y = -p.y;
  }
  if (mirror) std::reverse(pts.begin(), pts.end());
  return place(pts, c, angle);
}

Poly triangle(cv::Point2d c, double s, double angle) {
  return place({{-s / 2, s * 0.35}, {s / 2, s * 0.35}, {-s * 0.2, -s * 0.55}}, c, angle);
}

Poly star(cv::Point2d c, double ro, double ri, int n, double angle) {
  std::vector<cv::Point2d> pts;
  for (int i = 0; i < 2 * n; ++i) {
    double r = i % 2 ? ri : ro, t = M_PI * i / n;
    pts.emplace_back(r * std::cos(t), r * std::sin(t));
  }
  return place(pts, c, angle);
}

Poly regular(cv::Point2d c, double r, int sides, double angle) {
  std::vector<cv::Point2d> pts;
  for (int i = 0; i < sides; ++i) pts.emplace_back(r * std::cos(2 * M_PI * i / sides), r * std::sin(2 * M_PI * i / sides));
  return place(pts, c, angle);
}

cv::Point2d poly_centroid(const Poly& p) {
  double a = 0, cx = 0, cy = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& v = p[(i + 1) % p.size()];
    double cr = u.x * v.y - v.x * u.y;
    a += cr, cx += (u.x + v.x) * cr, cy += (u.y + v.y) * cr;
  }
  return {cx / (3 * a), cy / (3 * a)};
}

double min_chord(const Poly& p, cv::Point2d c) {
  double best = 1e300;
  for (double deg = 0; deg < 180; deg += 0.05) {
    double ux = std::cos(deg * M_PI / 180), uy = std::sin(deg * M_PI / 180);
    double tmin = 1e300, tmax = -1e300;
    for (size_t i = 0; i < p.size(); ++i) {
      cv::Point2d a = p[i] - c, d = p[(i + 1) % p.size()] - p[i];
      double den = ux * d.y - uy * d.x;
      if (std::abs(den) < 1e-12) continue;
      double s = (a.x * uy - a.y * ux) / den;
      if (s < 0 || s >= 1) continue;
      double t = (a.x * d.y - a.y * d.x) / den;
      tmin = std::min(tmin, t), tmax = std::max(tmax, t);
    }
    if (tmax > tmin) best = std::min(best, tmax - tmin);
  }
  return best;
}

cv::Mat render(const Scene& s, const std::vector<Poly>& polys) {
  constexpr int k = 8;
  cv::Mat big(s.size.height * k, s.size.width * k, CV_8U, cv::Scalar(0));
  for (const Poly& p : polys) {
    std::vector<cv::Point> q;
    // Pixel centre (x, y) covers [x - 0.5, x + 0.5]; in the big image that is [k x, k x + k).
    for (const auto& v : p) q.emplace_back(int(std::lround(((v.x + 0.5) * k - 0.5) * 16)), int(std::lround(((v.y + 0.5) * k - 0.5) * 16)));
    std::vector<std::vector<cv::Point>> qs{q};
    cv::fillPoly(big, qs, cv::Scalar(255), cv::LINE_8, 4);
  }
  cv::Mat cover;
  cv::resize(big, cover, s.size, 0, 0, cv::INTER_AREA);
  cv::Mat f;
  cover.convertTo(f, CV_32F, 1.0 / 255);
  cv::Mat img = s.background + (s.object - s.background) * f;
  if (s.light_gradient != 0) {
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) img.at<float>(y, x) += float(s.light_gradient * x / img.cols);
  }
  if (s.blur_sigma > 0) cv::GaussianBlur(img, img, cv::Size(), s.blur_sigma);
  if (s.noise_sigma > 0) {
    cv::RNG rng(s.seed);
    cv::Mat n(img.size(), CV_32F);
    rng.fill(n, cv::RNG::NORMAL, 0, s.noise_sigma);
    img += n;
  }
  cv::Mat g8, bgr;
  img.convertTo(g8, CV_8U);
  cv::cvtColor(g8, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

cv::Mat coverage(const std::vector<Poly>& polys) {
  Scene cover;
  cover.background = 0, cover.object = 255;
  cv::Mat c8, alpha;
  cv::cvtColor(render(cover, polys), c8, cv::COLOR_BGR2GRAY);
  c8.convertTo(alpha, CV_32F, 1.0 / 255);
  return alpha;
}

cv::Mat camera(cv::Mat img, double noise_sigma, unsigned seed) {
  cv::GaussianBlur(img, img, cv::Size(), 1.0);
  cv::Mat noise(img.size(), CV_32F);
  cv::RNG(seed).fill(noise, cv::RNG::NORMAL, 0, noise_sigma);
  cv::Mat out;
  cv::Mat(img + noise).convertTo(out, CV_8U);
  return out;
}

}  // namespace rbx1::vision::test
