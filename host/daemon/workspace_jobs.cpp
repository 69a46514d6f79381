// workspace_jobs.cpp - rbx1 calibrate-workspace as requests a CLI or a web page can drive: start (markers at the scan
// pose), status, record (the tool point on marker i), fit (RMS, leave-one-out), save (atomic), cancel.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <spdlog/spdlog.h>

#include "calibration.hpp"
#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "machine.hpp"

namespace rbx1::daemon {

namespace {

double round3(double v) { return std::round(v * 1000) / 1000; }
nlohmann::json point(cv::Point2d p) { return {round3(p.x), round3(p.y)}; }

nlohmann::json markers_json(const WorkspaceSession& s) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& m : s.markers) {
    nlohmann::json corners = nlohmann::json::array();
    for (const auto& c : m.corners) corners.push_back(point(c));
    nlohmann::json j{{"id", m.id}, {"centre_px", point(m.centre)}, {"corners_px", corners}};
    auto t = s.touched.find(m.id);
    j["recorded_mm"] = t == s.touched.end() ? nlohmann::json(nullptr) : point(t->second.mm);
    a.push_back(j);
  }
  return a;
}

const calib::DetectedMarker* find_marker(const WorkspaceSession& s, int id) {
  for (const auto& m : s.markers)
    if (m.id == id) return &m;
  return nullptr;
}

std::vector<calib::WorkspacePoint> recorded_points(const WorkspaceSession& s) {
  std::vector<calib::WorkspacePoint> pts;
  for (const auto& [id, t] : s.touched) pts.push_back({id, find_marker(s, id)->centre, t.mm});
  return pts;
}


// Why the fit may not be saved ([operator] max_rms_mm, max_loo_mm), or "".
std::string rejection(const calib::WorkspaceFit& fit, const OperatorConfig& op) {
  if (fit.rms_mm > op.max_rms_mm)
    return "RMS residual " + std::to_string(fit.rms_mm).substr(0, 5) + " mm is above [operator] max_rms_mm = " +
           std::to_string(op.max_rms_mm).substr(0, 5);
  if (fit.max_loo_mm > op.max_loo_mm)
    return "a leave-one-out error of " + std::to_string(fit.max_loo_mm).substr(0, 5) +
           " mm is above [operator] max_loo_mm = " + std::to_string(op.max_loo_mm).substr(0, 5) +
           " (re-record the marker with the largest)";
  return "";
}

// The table as the arm's own kinematics reaches it: the touches' mean height (link-length errors move it by
// millimetres, enough for fingers planned 2 mm above the nominal table to scrape the real one).
struct TableHeight {
  double z_mm, spread_mm;
};
TableHeight table_height(const WorkspaceSession& s) {
  double z_sum = 0, z_lo = 1e18, z_hi = -1e18;
  for (const auto& [id, t] : s.touched) {
    z_sum += t.z_mm;
    z_lo = std::min(z_lo, t.z_mm);
    z_hi = std::max(z_hi, t.z_mm);
  }
  return {z_sum / double(s.touched.size()), z_hi - z_lo};
}

// The fit's refusal as the error list names it.
ErrorCode fit_error(calib::FitRefusal why) {
  switch (why) {
    case calib::FitRefusal::TooFewMarkers: return ErrorCode::TooFewMarkers;
    case calib::FitRefusal::DuplicateMarker: return ErrorCode::DuplicateMarker;
    case calib::FitRefusal::Degenerate: return ErrorCode::Degenerate;
  }
  return ErrorCode::Internal;
}

nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(round3(v)) : nlohmann::json(nullptr); }

// The fit's figures: per recorded marker its residual and leave-one-out error, and where the map puts every marker
// seen, recorded or not (a page can draw them; unrecorded ones are a check).
nlohmann::json fit_json(const calib::WorkspaceFit& fit, const std::vector<calib::WorkspacePoint>& points,
                        const WorkspaceSession& s, const TableHeight& table, const OperatorConfig& op) {
  nlohmann::json per = nlohmann::json::array();
  for (size_t i = 0; i < points.size(); ++i)
    per.push_back({{"id", points[i].id}, {"residual_mm", round3(fit.residual_mm[i])}, {"loo_mm", finite_or_null(fit.loo_mm[i])}});
  nlohmann::json predicted = nlohmann::json::array();
  for (const auto& m : s.markers) predicted.push_back({{"id", m.id}, {"mm", point(calib::apply_map(fit.h, m.centre))}});
  return {{"model", fit.model}, {"rms_mm", round3(fit.rms_mm)},
          {"table_z_mm", round3(table.z_mm)}, {"table_z_spread_mm", round3(table.spread_mm)},
          {"max_loo_mm", finite_or_null(fit.max_loo_mm)}, {"markers", per}, {"predicted", predicted},
          {"bounds", {{"max_rms_mm", op.max_rms_mm}, {"max_loo_mm", op.max_loo_mm}}}};
}

}  // namespace

void Machine::job_calibrate_workspace(Reply& reply, const Request& r) {
  const std::string& a = r.action;
  const char* in_force = config_.arm.camera.pixel_map ? "workspace" : "mount";
  if (a == "cancel") {
    bool was = workspace_ != nullptr;
    workspace_.reset();
    reply.result({{"cancelled", was}, {"in_force", in_force}});
    return;
  }
  if (a == "status") {
    nlohmann::json j{{"active", workspace_ != nullptr}, {"in_force", in_force}};
    if (workspace_) {
      j["markers"] = markers_json(*workspace_);
      j["recorded"] = workspace_->touched.size();
    }
    reply.result(j);
    return;
  }
  if (a == "start") return workspace_start(reply, in_force);
  if (!workspace_) {
    reply.error(ErrorCode::NoCalibration, "no workspace calibration in progress (calibrate_workspace start)");
    return;
  }
  if (a == "record") return workspace_record(reply, r.index);
  workspace_fit(reply, a == "save");
}

void Machine::workspace_start(Reply& reply, const char* in_force) {
  if (!ready(reply)) return;
  if (!move_to(reply, "scan_pose", config_.arm.scan)) return;
  cv::Mat frame;
  if (!capture(reply, frame)) return;
  reply.event("captured", {{"source", camera_->describe()}, {"width", frame.cols}, {"height", frame.rows}});
  // Perception works on the undistorted frame; the markers are found in the same one, so the map fits its pixels.
  std::string error;
  if (!config_.vision.calibration_path.empty()) {
    calib::Calibration c;
    if (!calib::load_calibration(config_.vision.calibration_path, c, error)) {
      reply.error(ErrorCode::VisionFailed, error);
      return;
    }
    frame = c.undistort(frame);
  }
  auto s = std::make_unique<WorkspaceSession>();
  std::vector<int> duplicates;
  if (!calib::detect_markers(frame, config_.op.marker_dictionary, s->markers, duplicates, error)) {
    reply.error(ErrorCode::VisionFailed, error);
    return;
  }
  s->image_size = frame.size();
  if (int(s->markers.size()) < config_.op.min_markers) {
    reply.error(ErrorCode::TooFewMarkers, std::to_string(s->markers.size()) + " " + config_.op.marker_dictionary +
                                       " markers seen at the scan pose; lay at least " +
                                       std::to_string(config_.op.min_markers) +
                                       " inside the camera's view (rbx1 markers prints them); the old calibration stays");
    return;
  }
  workspace_ = std::move(s);  // a new start replaces a session in progress
  nlohmann::json j{{"markers", markers_json(*workspace_)}, {"image", {{"width", frame.cols}, {"height", frame.rows}}},
                   {"dictionary", config_.op.marker_dictionary}, {"min_markers", config_.op.min_markers},
                   {"in_force", in_force}};
  if (!duplicates.empty()) j["duplicates_ignored"] = duplicates;
  reply.result(j);
}

void Machine::workspace_record(Reply& reply, int marker) {
  WorkspaceSession& s = *workspace_;
  if (!find_marker(s, marker)) {
    std::string seen;
    for (const auto& m : s.markers) seen += (seen.empty() ? "" : ", ") + std::to_string(m.id);
    reply.error(ErrorCode::UnknownMarker, "marker " + std::to_string(marker) + " was not seen at the scan pose (seen: " + seen + ")");
    return;
  }
  if (!ready(reply)) return;
  arm::Steps cur;
  arm::Joints deg;
  if (!current_pose(reply, cur, deg)) return;
  arm::ToolPose tp = arm::tool_pose(config_.arm.links, deg);
  double above = tp.z_mm - config_.arm.heights.table_z_mm;
  if (std::fabs(above) > config_.op.touch_max_height_mm) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "the tool point is %.1f mm %s the table (z %.1f mm): jog it onto the marker's centre "
                  "(within [operator] touch_max_height_mm = %g)", std::fabs(above), above > 0 ? "above" : "below",
                  tp.z_mm, config_.op.touch_max_height_mm);
    reply.error(ErrorCode::NotOnTable, buf);
    return;
  }
  s.touched[marker] = {{tp.x_mm, tp.y_mm}, tp.z_mm};
  nlohmann::json remaining = nlohmann::json::array();
  for (const auto& m : s.markers)
    if (!s.touched.count(m.id)) remaining.push_back(m.id);
  reply.result({{"marker", marker}, {"px", point(find_marker(s, marker)->centre)},
                {"mm", {round3(tp.x_mm), round3(tp.y_mm), round3(tp.z_mm)}}, {"recorded", s.touched.size()},
                {"remaining", remaining}});
}

void Machine::workspace_fit(Reply& reply, bool save) {
  // The least-squares map over the recorded markers.
  WorkspaceSession& s = *workspace_;
  calib::WorkspaceFit fit;
  calib::FitRefusal why{};
  std::string error;
  auto points = recorded_points(s);
  if (!calib::fit_workspace(points, config_.op.min_markers, fit, why, error)) {
    reply.error(fit_error(why), error + "; the old calibration stays");
    return;
  }
  std::string reason = rejection(fit, config_.op);
  TableHeight table = table_height(s);
  nlohmann::json result = fit_json(fit, points, s, table, config_.op);
  result["accepted"] = reason.empty();
  if (!reason.empty()) result["reason"] = reason;
  if (!save) return reply.result(result);
  if (!reason.empty()) {
    reply.error(ErrorCode::FitRejected, reason + "; nothing saved, the old calibration stays");
    return;
  }
  calib::WorkspaceCalibration w{fit, s.image_size, points, table.z_mm};
  if (!state_->ensure(error) || !calib::save_workspace(state_->path(kWorkspaceFile), w, error)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  arm::CameraMount::PixelMap m;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) m.h[i * 3 + k] = fit.h(i, k);
  m.width = s.image_size.width;
  m.height = s.image_size.height;
  workspace_.reset();
  {
    std::lock_guard lock(mutex_);  // the scene request reads the arm's config
    config_.arm.camera.pixel_map = m;
    config_.arm.heights.table_z_mm = table.z_mm;
    calibration_ = calibration_summary(&w);
  }
  spdlog::info("workspace calibration saved: {} over {} markers, RMS {:.3f} mm, worst leave-one-out {:.3f} mm, table "
               "at z {:.2f} mm", fit.model, points.size(), fit.rms_mm, fit.max_loo_mm, table.z_mm);
  result["saved"] = state_->path(kWorkspaceFile);
  result["in_force"] = "workspace";
  reply.result(result);
}

nlohmann::json Machine::calibration_summary(const calib::WorkspaceCalibration* w) const {
  if (!w) return {{"in_force", "mount"}};
  return {{"in_force", "workspace"}, {"model", w->fit.model}, {"markers", w->points.size()},
          {"rms_mm", round3(w->fit.rms_mm)}, {"max_loo_mm", round3(w->fit.max_loo_mm)},
          {"table_z_mm", w->table_z_mm ? nlohmann::json(round3(*w->table_z_mm)) : nlohmann::json(nullptr)},
          {"file", state_->path(kWorkspaceFile)}};
}

}  // namespace rbx1::daemon
