// vision.cpp - Vision: loads the background, library and scale once, then turns frames into detections and scans.
#include "vision.hpp"

#include <cmath>
#include <cstdio>

#include "image_io.hpp"
#include "scan_json.hpp"

namespace rbx1::vision {
namespace {

// Rounds to a multiple of q (a power of ten), so the JSON prints short decimals.
double round_to(double v, double q) { return std::round(v / q) / std::round(1 / q); }
cv::Point2d pt(cv::Point2d p, double q) { return {round_to(p.x, q), round_to(p.y, q)}; }

}  // namespace

bool parse_polarity(const std::string& text, Polarity& out) {
  if (text == "auto") out = Polarity::Auto;
  else if (text == "dark") out = Polarity::Dark;
  else if (text == "light") out = Polarity::Light;
  else return false;
  return true;
}

void parse_vision_config(rbx1::config::Section v, VisionOptions& out) {
  out.background_path = v.string("background", out.background_path);
  std::string pol = v.string("objects", "auto");
  if (!parse_polarity(pol, out.objects)) v.errors().add(v.path().empty() ? "objects" : v.path() + ".objects",
                                                        "must be \"auto\", \"dark\" or \"light\", got \"" + pol + "\"");
  out.library_path = v.string("library", out.library_path);
  out.px_per_cm = v.number("px_per_cm", out.px_per_cm, 0, 1e5);
  out.calibration_path = v.string("calibration", out.calibration_path);
  out.gripper_max_cm = v.number("gripper_max_cm", out.gripper_max_cm, 0.1, 100);
  out.gripper_min_cm = v.number("gripper_min_cm", out.gripper_min_cm, 0, 100);
  out.gripper_min_px = v.number("gripper_min_px", out.gripper_min_px, 0, 10000);
  out.finger_width_cm = v.number("finger_width_cm", out.finger_width_cm, 0, 20);
  out.finger_depth_cm = v.number("finger_depth_cm", out.finger_depth_cm, 0, 20);
  out.finger_width_px = v.number("finger_width_px", out.finger_width_px, 0, 1000);
  out.finger_depth_px = v.number("finger_depth_px", out.finger_depth_px, 0, 1000);
  out.min_area_px = int(v.integer("min_area_px", out.min_area_px, 0, 1'000'000));
  out.match_threshold = v.number("match_threshold", out.match_threshold, 0, 1);
  v.reject_unknown();
}

int min_area_for(cv::Size frame) {
  return std::max(12, int(std::lround(40.0 * double(frame.area()) / (640.0 * 480.0))));
}

std::unique_ptr<Vision> Vision::create(const VisionOptions& opt, std::string& error) {
  auto v = std::unique_ptr<Vision>(new Vision());
  v->opt_ = opt;
  if (opt.px_per_cm < 0 || !std::isfinite(opt.px_per_cm)) {
    error = "px_per_cm must be positive";
    return nullptr;
  }
  if (!(opt.gripper_max_cm > 0)) {
    error = "gripper_max_cm must be positive";
    return nullptr;
  }
  if (!(opt.gripper_min_cm >= 0 && opt.gripper_min_cm < opt.gripper_max_cm)) {
    error = "gripper_min_cm must be at least 0 and below gripper_max_cm";
    return nullptr;
  }
  if (!opt.calibration_path.empty()) {
    v->scale_ = scale_from_file(opt.calibration_path, error);
    if (!v->scale_) return nullptr;
  } else if (opt.px_per_cm > 0) {
    v->scale_ = scale_from_px_per_cm(opt.px_per_cm);
  }
  if (!opt.background_path.empty()) {
    cv::Mat bg;
    if (!read_image(opt.background_path, bg, error)) return nullptr;
    if (v->scale_) bg = v->scale_->undistort(bg);
    v->background_ = to_gray8(bg);
    if (bg.type() == CV_8UC3) v->background_bgr_ = bg;  // for the shadow test on a coloured table
  }
  if (!opt.library_path.empty()) {
    if (!load_library(opt.library_path, v->library_, error)) return nullptr;
    v->has_library_ = true;
  }
  DetectorOptions& d = v->det_;
  d.objects = opt.objects;
  d.isolation.min_area_px = opt.min_area_px;
  d.match.threshold = opt.match_threshold;
  return v;
}

bool Vision::run(const cv::Mat& frame, Detection& det, cv::Mat& processed, std::string& error) {
  if (!check_frame(frame, error)) return false;
  processed = scale_ ? scale_->undistort(frame) : frame;
  cv::Mat gray = to_gray8(processed);
  if (!background_.empty() && background_.size() != gray.size()) {
    error = "background is " + std::to_string(background_.cols) + "x" + std::to_string(background_.rows) +
            " but the frame is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows);
    return false;
  }
  DetectorOptions d = det_;
  if (opt_.min_area_px <= 0) d.isolation.min_area_px = min_area_for(gray.size());
  cv::Point2d centre((gray.cols - 1) / 2.0, (gray.rows - 1) / 2.0);
  if (scale_) {
    double s = scale_->px_per_cm_at(centre);
    d.px_per_cm = s;
    d.grip.finger_width_px = opt_.finger_width_cm * s;
    d.grip.finger_depth_px = opt_.finger_depth_cm * s;
    d.grip.min_opening_px = std::max(1.0, opt_.gripper_min_cm * s);
    d.grip.max_opening_px = opt_.gripper_max_cm * s;
  } else {
    d.grip.finger_width_px = opt_.finger_width_px;
    d.grip.finger_depth_px = opt_.finger_depth_px;
    d.grip.min_opening_px = std::max(1.0, opt_.gripper_min_px);
  }
  ColourImages colour{processed, background_bgr_};
  const bool in_colour = processed.type() == CV_8UC3 && !background_bgr_.empty();
  if (!detect(gray, background_, d, has_library_ ? &library_ : nullptr, det, error, in_colour ? &colour : nullptr))
    return false;
  for (DetectedObject& o : det.objects) {
    if (!scale_) continue;
    o.centroid_cm = scale_->to_cm(o.geometry.centroid);
    if (o.grip.reason == GripReason::NoContact) continue;
    // The scale varies over an undistorted frame: the exact opening in cm has the last word.
    o.grip.opening_cm = scale_->distance_cm(o.grip.p1, o.grip.p2);
    if (!o.grip.feasible) continue;
    if (*o.grip.opening_cm > opt_.gripper_max_cm) o.grip.reason = GripReason::TooWide;
    else if (*o.grip.opening_cm < opt_.gripper_min_cm) o.grip.reason = GripReason::TooNarrow;
    o.grip.feasible = o.grip.reason == GripReason::None;
  }
  return true;
}

LibraryEntry Vision::teach_entry(const Detection& det, size_t k, const std::string& name, bool mirror_ok,
                                 SelfViews* views) const {
  const DetectedObject& o = det.objects[k];
  LibraryEntry e;
  e.name = name;
  e.mirror_ok = mirror_ok;
  e.profile = det.profiles[k];
  e.area_px = o.geometry.half_area_px;
  e.area_kind = AreaKind::HalfLevel;
  e.elongation = o.pose.elongation;
  if (double ppc = px_per_cm_at(o.geometry.centroid); ppc > 0) e.area_cm2 = e.area_px / (ppc * ppc);
  SelfViews v = learn_threshold(o.geometry, e, det_.match, det_.pose, det_.grip.lines);
  e.threshold = v.threshold;
  if (views) *views = v;
  return e;
}

bool Vision::process(const cv::Mat& frame, nlohmann::json& result, std::string& error) {
  Detection det;
  cv::Mat processed;
  if (!run(frame, det, processed, error)) return false;
  result = scan(det);
  return true;
}

Scan Vision::scan(const Detection& det) const {
  Scan out;
  out.image = det.size;
  cv::Point2d centre((det.size.width - 1) / 2.0, (det.size.height - 1) / 2.0);
  if (scale_) out.px_per_cm = round_to(scale_->px_per_cm_at(centre), 1e-4);
  auto round_opt = [](const std::optional<double>& v, double q) { return v ? std::optional(round_to(*v, q)) : std::nullopt; };
  for (const DetectedObject& d : det.objects) {
    ScanObject o;
    o.index = d.index;
    o.identity = d.identity;
    o.identity.score = d.identity.label ? round_opt(d.identity.score, 1e-4) : std::nullopt;
    o.identity.best_score = round_opt(d.identity.best_score, 1e-4);
    o.identity.threshold = round_opt(d.identity.threshold, 1e-4);
    o.identity.runner_up_score = round_opt(d.identity.runner_up_score, 1e-4);
    o.centroid_px = pt(d.geometry.centroid, 1e-3);
    if (d.centroid_cm) o.centroid_cm = pt(*d.centroid_cm, 1e-4);
    o.area_px = std::lround(d.geometry.area_px);
    o.edge_points = d.geometry.edge_pixels;
    o.pose = d.pose;
    o.pose.orientation_deg = round_to(d.pose.orientation_deg, 1e-3);
    o.pose.slope = round_opt(d.pose.slope, 1e-5);
    o.pose.intercept = round_opt(d.pose.intercept, 1e-3);
    o.pose.elongation = round_to(d.pose.elongation, 1e-3);
    o.grip = d.grip;
    o.grip.p1 = pt(d.grip.p1, 1e-3);
    o.grip.p2 = pt(d.grip.p2, 1e-3);
    o.grip.opening_px = round_to(d.grip.opening_px, 1e-3);
    o.grip.opening_cm = round_opt(d.grip.opening_cm, 1e-4);
    o.grip.angle_deg = round_to(d.grip.angle_deg, 1e-3);
    o.touching = d.touching;
    out.objects.push_back(std::move(o));
  }
  out.warnings = det.warnings;
  return out;
}

std::string Vision::report(const Detection& det) const {
  std::string out;
  char line[256];
  for (const std::string& w : det.warnings) out += "Warning: " + w + "\n";
  if (det.objects.empty()) return out + "No objects found.\n";
  for (const DetectedObject& o : det.objects) {
    std::snprintf(line, sizeof line, "Data for object #%d\n", o.index);
    out += line;
    if (has_library_) {
      if (o.identity.label) std::snprintf(line, sizeof line, "Identified as %s (match %.2f)\n", o.identity.label->c_str(), *o.identity.score);
      else if (o.identity.best)
        std::snprintf(line, sizeof line, "Identified as unknown (%s: nearest %s, match %.2f, its threshold %.2f)\n",
                      verdict_name(o.identity.verdict), o.identity.best->c_str(), *o.identity.best_score,
                      *o.identity.threshold);
      else std::snprintf(line, sizeof line, "Identified as unknown\n");
      out += line;
    }
    if (o.centroid_cm) std::snprintf(line, sizeof line, "Centre at %.2f cm, %.2f cm\n", o.centroid_cm->x, o.centroid_cm->y);
    else std::snprintf(line, sizeof line, "Centre at %.2f px, %.2f px\n", o.geometry.centroid.x, o.geometry.centroid.y);
    out += line;
    if (o.grip.opening_cm) std::snprintf(line, sizeof line, "Gripper opening = %.2f cm\n", *o.grip.opening_cm);
    else std::snprintf(line, sizeof line, "Gripper opening = %.2f px\n", o.grip.opening_px);
    out += line;
    std::snprintf(line, sizeof line, "Gripper orientation: %.2f degrees w.r.t. robotic arm horizontal reference axis.\n",
                  o.grip.angle_deg);
    out += line;
    switch (o.grip.feasible ? GripReason::None : o.grip.reason) {
      case GripReason::TooWide: out += "Not pickable: wider than the gripper.\n"; break;
      case GripReason::TooNarrow: out += "Not pickable: narrower than the gripper's smallest opening.\n"; break;
      case GripReason::NoContact: out += "Not pickable: no closing line meets the object on both sides.\n"; break;
      case GripReason::FingerCollision: out += "Not pickable: every grip puts a finger on a neighbouring object.\n"; break;
      case GripReason::None: break;
    }
  }
  return out;
}

}  // namespace rbx1::vision
