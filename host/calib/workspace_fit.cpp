// workspace_fit.cpp - pixel -> base-frame map by least squares (homography or affine), leave-one-out errors, the file.
#include "workspace_fit.hpp"

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>

#include "atomic_file.hpp"

namespace rbx1::calib {

namespace {

// Smallest / largest singular value of the centred points: ~0 for points on a line (or all in one place).
double spread_ratio(const std::vector<cv::Point2d>& p) {
  cv::Point2d c(0, 0);
  for (const auto& q : p) c += q;
  c *= 1.0 / double(p.size());
  double sxx = 0, syy = 0, sxy = 0;
  for (const auto& q : p) {
    cv::Point2d d = q - c;
    sxx += d.x * d.x;
    syy += d.y * d.y;
    sxy += d.x * d.y;
  }
  double tr = sxx + syy, det = sxx * syy - sxy * sxy;
  double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
  double l1 = tr / 2 + disc, l2 = tr / 2 - disc;
  return l1 <= 0 ? 0 : std::sqrt(std::max(0.0, l2) / l1);
}

bool fit_affine(const std::vector<cv::Point2d>& px, const std::vector<cv::Point2d>& mm, cv::Matx33d& h) {
  const int n = int(px.size());
  cv::Mat a(2 * n, 6, CV_64F, cv::Scalar(0)), b(2 * n, 1, CV_64F);
  for (int i = 0; i < n; ++i) {
    double row[3] = {px[i].x, px[i].y, 1.0};
    for (int k = 0; k < 3; ++k) {
      a.at<double>(2 * i, k) = row[k];
      a.at<double>(2 * i + 1, 3 + k) = row[k];
    }
    b.at<double>(2 * i) = mm[i].x;
    b.at<double>(2 * i + 1) = mm[i].y;
  }
  cv::Mat x;
  if (!cv::solve(a, b, x, cv::DECOMP_SVD)) return false;
  h = cv::Matx33d(x.at<double>(0), x.at<double>(1), x.at<double>(2), x.at<double>(3), x.at<double>(4), x.at<double>(5), 0, 0, 1);
  return true;
}

// Homography (DLT, then OpenCV's Levenberg-Marquardt refinement of the error in mm) or affine; false if singular.
bool fit_model(bool homography, const std::vector<cv::Point2d>& px, const std::vector<cv::Point2d>& mm, cv::Matx33d& h) {
  if (!homography) return fit_affine(px, mm, h);
  cv::Mat m = cv::findHomography(px, mm, 0);
  if (m.empty()) return false;
  h = cv::Matx33d(m);
  return std::isfinite(cv::determinant(h)) && std::fabs(cv::determinant(h)) > 1e-15;
}

double distance(cv::Point2d a, cv::Point2d b) { return std::hypot(a.x - b.x, a.y - b.y); }

}  // namespace

cv::Point2d apply_map(const cv::Matx33d& h, cv::Point2d p) {
  cv::Vec3d v = h * cv::Vec3d(p.x, p.y, 1.0);
  return {v[0] / v[2], v[1] / v[2]};
}

bool fit_workspace(const std::vector<WorkspacePoint>& points, int min_points, WorkspaceFit& out, FitRefusal& why,
                   std::string& error) {
  const int n = int(points.size());
  min_points = std::max(min_points, 4);
  if (n < min_points) {
    why = FitRefusal::TooFewMarkers;
    error = std::to_string(n) + " marker" + (n == 1 ? "" : "s") + " recorded; at least " + std::to_string(min_points) +
            " are needed, spread over the view (not on one line)";
    return false;
  }
  std::set<int> ids;
  std::vector<cv::Point2d> px, mm;
  for (const auto& p : points) {
    if (!ids.insert(p.id).second) {
      why = FitRefusal::DuplicateMarker;
      error = "marker " + std::to_string(p.id) + " recorded twice";
      return false;
    }
    px.push_back(p.px);
    mm.push_back(p.mm);
  }
  // A line of markers fixes nothing across it; 0.1 = the narrow side is a tenth of the long one.
  constexpr double kMinSpread = 0.1;
  double sp = spread_ratio(px), sm = spread_ratio(mm);
  if (sp < kMinSpread || sm < kMinSpread) {
    why = FitRefusal::Degenerate;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the markers are (nearly) collinear (spread %.3f in the image, %.3f on the table; needs %.1f): "
                  "place them around the view, not on a line",
                  sp, sm, kMinSpread);
    error = buf;
    return false;
  }
  const bool homography = n >= 5;
  WorkspaceFit f;
  f.model = homography ? "homography" : "affine";
  if (!fit_model(homography, px, mm, f.h)) {
    why = FitRefusal::Degenerate;
    error = "the markers do not determine a map (three or more on one line?)";
    return false;
  }
  double ss = 0;
  for (int i = 0; i < n; ++i) {
    double r = distance(apply_map(f.h, px[i]), mm[i]);
    f.residual_mm.push_back(r);
    ss += r * r;
  }
  f.rms_mm = std::sqrt(ss / n);
  // Leave one out: the honest error of each marker, which its own point cannot pull towards itself.
  for (int i = 0; i < n; ++i) {
    std::vector<cv::Point2d> p2, m2;
    for (int k = 0; k < n; ++k)
      if (k != i) {
        p2.push_back(px[k]);
        m2.push_back(mm[k]);
      }
    cv::Matx33d h;
    double e = std::numeric_limits<double>::infinity();
    if (spread_ratio(p2) >= kMinSpread && fit_model(homography, p2, m2, h)) e = distance(apply_map(h, px[i]), mm[i]);
    f.loo_mm.push_back(e);
    f.max_loo_mm = std::max(f.max_loo_mm, e);
  }
  if (!std::isfinite(f.rms_mm)) {
    why = FitRefusal::Degenerate;
    error = "the fit is not finite";
    return false;
  }
  out = f;
  return true;
}

bool save_workspace(const std::string& path, const WorkspaceCalibration& c, std::string& error) {
  using nlohmann::json;
  json h = json::array();
  for (int r = 0; r < 3; ++r) h.push_back({c.fit.h(r, 0), c.fit.h(r, 1), c.fit.h(r, 2)});
  json pts = json::array();
  for (size_t i = 0; i < c.points.size(); ++i) {
    const auto& p = c.points[i];
    json j{{"id", p.id}, {"px", {p.px.x, p.px.y}}, {"mm", {p.mm.x, p.mm.y}}};
    if (i < c.fit.residual_mm.size()) j["residual_mm"] = c.fit.residual_mm[i];
    if (i < c.fit.loo_mm.size() && std::isfinite(c.fit.loo_mm[i])) j["loo_mm"] = c.fit.loo_mm[i];
    pts.push_back(j);
  }
  json doc{{"format", "rbx1-workspace"}, {"version", 1},           {"model", c.fit.model},
           {"homography", h},             {"image_size", {c.image_size.width, c.image_size.height}},
           {"rms_mm", c.fit.rms_mm},      {"max_loo_mm", std::isfinite(c.fit.max_loo_mm) ? json(c.fit.max_loo_mm) : json(nullptr)},
           {"points", pts}};
  if (c.table_z_mm) doc["table_z_mm"] = *c.table_z_mm;
  return rbx1::write_file_atomic(path, doc.dump(2) + "\n", error);
}

bool load_workspace(const std::string& path, WorkspaceCalibration& out, std::string& error) {
  using nlohmann::json;
  std::ifstream f(path);
  if (!f) {
    error = path + ": cannot open";
    return false;
  }
  std::stringstream ss;
  ss << f.rdbuf();
  json doc = json::parse(ss.str(), nullptr, false);
  auto bad = [&](const std::string& why) {
    error = path + ": " + why;
    return false;
  };
  if (doc.is_discarded() || !doc.is_object()) return bad("not valid JSON");
  if (doc.value("format", "") != "rbx1-workspace") return bad("\"format\" must be \"rbx1-workspace\"");
  if (!doc["version"].is_number_integer() || doc["version"].get<int>() != 1) return bad("unsupported \"version\" (1 is)");
  const json& h = doc["homography"];
  if (!h.is_array() || h.size() != 3) return bad("\"homography\" must be 3x3 numbers");
  WorkspaceCalibration c;
  for (int r = 0; r < 3; ++r) {
    if (!h[r].is_array() || h[r].size() != 3) return bad("\"homography\" must be 3x3 numbers");
    for (int k = 0; k < 3; ++k) {
      if (!h[r][k].is_number() || !std::isfinite(h[r][k].get<double>())) return bad("\"homography\" must be 3x3 finite numbers");
      c.fit.h(r, k) = h[r][k].get<double>();
    }
  }
  if (std::fabs(cv::determinant(c.fit.h)) < 1e-15) return bad("\"homography\" is singular");
  const json& size = doc["image_size"];
  if (!size.is_array() || size.size() != 2 || !size[0].is_number_integer() || !size[1].is_number_integer() ||
      size[0].get<int>() <= 0 || size[1].get<int>() <= 0)
    return bad("\"image_size\" must be [width, height]");
  c.image_size = {size[0].get<int>(), size[1].get<int>()};
  c.fit.model = doc.value("model", "homography");
  if (!doc["rms_mm"].is_number()) return bad("\"rms_mm\" must be a number");
  c.fit.rms_mm = doc["rms_mm"].get<double>();
  c.fit.max_loo_mm = doc["max_loo_mm"].is_number() ? doc["max_loo_mm"].get<double>() : 0.0;
  if (doc.contains("table_z_mm")) {
    if (!doc["table_z_mm"].is_number() || !std::isfinite(doc["table_z_mm"].get<double>()))
      return bad("\"table_z_mm\" must be a number");
    c.table_z_mm = doc["table_z_mm"].get<double>();
  }
  if (doc.contains("points") && doc["points"].is_array())
    for (const auto& p : doc["points"]) {
      if (!p.is_object() || !p["px"].is_array() || !p["mm"].is_array() || p["px"].size() != 2 || p["mm"].size() != 2)
        return bad("\"points\" entries need \"id\", \"px\" and \"mm\"");
      c.points.push_back({p.value("id", 0), {p["px"][0].get<double>(), p["px"][1].get<double>()},
                          {p["mm"][0].get<double>(), p["mm"][1].get<double>()}});
      c.fit.residual_mm.push_back(p.value("residual_mm", 0.0));
      c.fit.loo_mm.push_back(p.value("loo_mm", 0.0));
    }
  out = c;
  return true;
}

}  // namespace rbx1::calib
