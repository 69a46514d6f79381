// operator_jobs.cpp - the operator's jobs: jog (joints or the tool point, limits first, dead-man stop), save the scan
// pose or a place, capture the background, teach an object from the live scan. Taught data goes to the state dir.
#include <cmath>
#include <cstdio>

#include <spdlog/spdlog.h>

#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "background.hpp"
#include "identify.hpp"
#include "library.hpp"
#include "machine.hpp"
#include "pick_plan.hpp"

namespace rbx1::daemon {

namespace {

double round3(double v) { return std::round(v * 1000) / 1000; }

nlohmann::json tool_json(const arm::ToolPose& t) {
  return {{"x_mm", round3(t.x_mm)}, {"y_mm", round3(t.y_mm)}, {"z_mm", round3(t.z_mm)}, {"yaw_deg", round3(t.yaw_deg)},
          {"tilt_deg", round3(t.tilt_deg)}};
}

nlohmann::json joints_json(const arm::Joints& d) {
  nlohmann::json a = nlohmann::json::array();
  for (double v : d) a.push_back(round3(v));
  return a;
}

std::string fmt(const char* f, double a, double b = 0) {
  char buf[120];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

}  // namespace

bool Machine::current_pose(Reply& reply, arm::Steps& steps, arm::Joints& deg) {
  rbx1_status_resp st{};
  if (int r = link_.status(st); r < 0) {
    reply.error(ErrorCode::LinkDown, link::failed(link_.name(), "STATUS", r));
    return false;
  }
  note_status(st);
  for (int i = 0; i < RBX1_JOINTS; ++i) steps[i] = st.position[i];
  deg = arm::steps_to_joints(config_.arm, steps);
  return true;
}

bool Machine::reload_vision(Reply& reply) {
  std::string error;
  auto v = vision::Vision::create(config_.vision, error);
  if (!v) {
    reply.error(ErrorCode::VisionFailed, error);
    return false;
  }
  vision_ = std::move(v);
  return true;
}

void Machine::job_jog(Reply& reply, const Request& r) {
  if (!ready(reply)) return;
  arm::Steps cur;
  arm::Joints deg;
  if (!current_pose(reply, cur, deg)) return;
  const arm::ArmConfig& cfg = config_.arm;
  arm::Joints target = deg;
  std::string error;
  // Everything is checked before anything moves: the bound of one request, the joint limits, the reach.
  if (r.joint > 0) {
    const int j = r.joint - 1;
    const auto& jc = cfg.joints[j];
    arm::Steps t = cur;
    t[j] = r.by_steps ? cur[j] + r.steps : arm::angle_to_steps(jc, arm::steps_to_angle(jc, cur[j]) + r.deg);
    target = arm::steps_to_joints(cfg, t);
    // The amount asked for (the step rounding may add up to half a step to it).
    double change = r.by_steps ? std::fabs(r.steps) * 360.0 / arm::steps_per_rev(jc) : std::fabs(r.deg);
    if (change > config_.op.jog_max_deg + 1e-9) {
      reply.error(ErrorCode::JogTooFar, "J" + std::to_string(r.joint) + fmt(" jog of %.2f deg is above [operator] jog_max_deg = %g", change,
                                                                     config_.op.jog_max_deg) + "; nothing moved");
      return;
    }
  } else {
    double dist = std::sqrt(r.mm[0] * r.mm[0] + r.mm[1] * r.mm[1] + r.mm[2] * r.mm[2]);
    if (dist > config_.op.jog_max_mm + 1e-9) {
      reply.error(ErrorCode::JogTooFar, fmt("tool jog of %.1f mm is above [operator] jog_max_mm = %g", dist, config_.op.jog_max_mm) +
                                     "; nothing moved");
      return;
    }
    arm::ToolPose tp = arm::tool_pose(cfg.links, deg);
    if (tp.tilt_deg > 1.0) {
      reply.error(ErrorCode::BadPose, fmt("a tool-point jog keeps the tool pointing down, but it is tilted %.1f deg: jog the "
                                  "joints or go to the scan pose first; nothing moved", tp.tilt_deg));
      return;
    }
    arm::Grasp g{tp.x_mm + r.mm[0], tp.y_mm + r.mm[1], tp.z_mm + r.mm[2], tp.yaw_deg};
    if (g.z_mm < cfg.heights.table_z_mm - 1e-6) {
      reply.error(ErrorCode::OutOfLimits, fmt("the tool point would go %.2f mm below the table (z %.2f mm); nothing moved",
                                       cfg.heights.table_z_mm - g.z_mm, g.z_mm));
      return;
    }
    if (!arm::ik(cfg, g, deg, target, error)) {
      reply.error(ErrorCode::OutOfLimits, error + "; nothing moved");
      return;
    }
  }
  if (!arm::check_limits(cfg, target, error)) {
    reply.error(ErrorCode::OutOfLimits, error + "; nothing moved");
    return;
  }
  rbx1_status_resp st{};
  for (int i = 0; i < RBX1_JOINTS; ++i) st.position[i] = cur[i];
  std::vector<MotionStep> steps;
  if (!plan_pose_move(cfg, st, "jog", target, steps, error)) {
    reply.error(ErrorCode::OutOfLimits, error + "; nothing moved");
    return;
  }
  // The dead-man rule: the move stops (STOP on the wire) as soon as the client that asked for it is gone.
  MotionHooks h = hooks(reply);
  auto base_aborted = h.aborted;
  auto base_reason = h.abort_reason;
  h.aborted = [base_aborted, &reply] { return base_aborted() || reply.client_gone(); };
  h.abort_reason = [base_aborted, base_reason] { return base_aborted() ? base_reason() : std::string(code_name(ErrorCode::ClientGone)); };
  Motion motion(link_, {config_.daemon.status_poll_ms, config_.daemon.move_timeout_s, config_.daemon.reconnect_timeout_s});
  MotionResult result = motion.run(steps, h);
  if (!result.ok) {
    if (result.failed_with(ErrorCode::ClientGone)) {
      rbx1_stop_resp sr{};
      int rs = link_.stop(sr);
      spdlog::warn("jog: the client went away mid-move: STOP sent ({})", rs < 0 ? link::error_text(rs) : "acknowledged");
    }
    if (result.failed_with(ErrorCode::Estop))
      reply.event("estop", {{"source", estop_source()}, {"firmware", status_json(result.last)}});
    reply.error(result.code, result.message);
    return;
  }
  arm::Steps now;
  for (int i = 0; i < RBX1_JOINTS; ++i) now[i] = result.last.position[i];
  arm::Joints now_deg = arm::steps_to_joints(cfg, now);
  nlohmann::json moved = nlohmann::json::array();
  for (int i = 0; i < RBX1_JOINTS; ++i) moved.push_back(int64_t(now[i]) - cur[i]);
  reply.result({{"moved_steps", moved}, {"position", now}, {"joints_deg", joints_json(now_deg)},
                {"tool", tool_json(arm::tool_pose(cfg.links, now_deg))}});
}

void Machine::job_pose_save(Reply& reply) {
  if (!ready(reply)) return;
  arm::Steps cur;
  arm::Joints deg;
  if (!current_pose(reply, cur, deg)) return;
  std::string error;
  if (!state_->save_scan_pose(deg, error)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  {
    std::lock_guard lock(mutex_);  // the scene request reads the arm's config
    config_.arm.scan = deg;
  }
  nlohmann::json r{{"pose", "scan"}, {"joints_deg", joints_json(deg)}, {"position", cur},
                   {"tool", tool_json(arm::tool_pose(config_.arm.links, deg))}, {"saved", state_->path(kPosesFile)}};
  if (config_.arm.camera.pixel_map)
    r["warning"] = "the workspace calibration was made at the previous scan pose: run rbx1 calibrate-workspace again";
  reply.result(r);
}

void Machine::job_place_save(Reply& reply, const std::string& name) {
  if (!ready(reply)) return;
  arm::Steps cur;
  arm::Joints deg;
  if (!current_pose(reply, cur, deg)) return;
  arm::ToolPose tp = arm::tool_pose(config_.arm.links, deg);
  if (tp.tilt_deg > 1.0) {
    reply.error(ErrorCode::BadPose, fmt("a place is where the tool points straight down, but it is tilted %.1f deg", tp.tilt_deg));
    return;
  }
  // The tool point (between the fingertips) on the surface: that surface's height is the place's z.
  arm::Place p{tp.x_mm, tp.y_mm, tp.z_mm, tp.yaw_deg};
  std::string error;
  if (!state_->save_place(name, p, error)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  {
    std::lock_guard lock(mutex_);  // status_reply lists the places
    config_.arm.places[name] = p;
  }
  reply.result({{"place", name}, {"x_mm", round3(p.x_mm)}, {"y_mm", round3(p.y_mm)}, {"z_mm", round3(p.z_mm)},
                {"yaw_deg", round3(p.yaw_deg)}, {"saved", state_->path(kPlacesFile)}});
}

void Machine::job_background(Reply& reply, int frames) {
  if (frames <= 0) frames = config_.op.background_frames;
  if (!ready(reply)) return;
  if (!move_to(reply, "scan_pose", config_.arm.scan)) return;
  // The mean of several frames (perception's average_background): sensor noise drops by sqrt(frames), and every
  // later scan subtracts this image.
  std::vector<cv::Mat> shots;
  for (int i = 0; i < frames; ++i) {
    cv::Mat frame;
    if (!capture(reply, frame)) return;
    shots.push_back(frame);
  }
  cv::Mat mean;
  if (std::string why; !vision::average_background(shots, mean, why)) {
    reply.error(ErrorCode::CameraFailed, camera_->describe() + ": " + why);
    return;
  }
  std::string error;
  if (!state_->save_background(mean, error)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  std::string old = config_.vision.background_path;
  config_.vision.background_path = state_->path(kBackgroundFile);
  if (!reload_vision(reply)) {
    config_.vision.background_path = old;
    return;
  }
  reply.event("captured", {{"source", camera_->describe()}, {"width", mean.cols}, {"height", mean.rows}, {"frames", frames}});
  reply.result({{"background", state_->path(kBackgroundFile)}, {"frames", frames}, {"width", mean.cols}, {"height", mean.rows}});
}

void Machine::job_teach(Reply& reply, const Request& r) {
  if (!ready(reply)) return;
  if (!move_to(reply, "scan_pose", config_.arm.scan)) return;
  cv::Mat frame;
  if (!capture(reply, frame)) return;
  vision::Detection det;
  cv::Mat processed;
  std::string error;
  if (!vision_->run(frame, det, processed, error)) {
    reply.error(ErrorCode::VisionFailed, error);
    return;
  }
  size_t k = 0;
  while (k < det.objects.size() && det.objects[k].index != r.index) ++k;
  if (k == det.objects.size()) {
    reply.error(ErrorCode::NoObject, "no object #" + std::to_string(r.index) + " in the live scan (" +
                                 std::to_string(det.objects.size()) + " found)");
    return;
  }
  // With the camera on the arm the part is taught as picks judge it: seen from straight above (look_before_picking).
  if (camera_->moves_with_arm()) {
    vision::Detection above;
    int under = -1;
    bool looked = false;
    if (!look_over(reply, det.size, vision_->scan(det).objects[k], above, under, looked)) return;
    if (looked && under < 0) {
      reply.error(ErrorCode::NoObject, "no object under the camera when it looked straight over #" +
                                           std::to_string(r.index));
      return;
    }
    if (looked) det = std::move(above), k = size_t(under);
  }
  const vision::LibraryEntry e = vision_->teach_entry(det, k, r.name, r.mirror_ok);
  // The state library starts as a copy of the configured one, so teaching adds to what the file taught.
  vision::Library lib;
  const std::string target = state_->path(kLibraryFile);
  const std::string from = config_.vision.library_path.empty() ? target : config_.vision.library_path;
  if (!vision::load_library(from, lib, error, /*allow_missing=*/from == target)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  // A second name for an object already taught makes twins: taught anyway, never silently (warnings).
  nlohmann::json warnings = nlohmann::json::array();
  for (const auto& t : vision::lookalikes(lib, e, vision_->detector_options().match))
    warnings.push_back(vision::lookalike_warning(r.name, t));
  vision::upsert(lib, e);
  if (!state_->ensure(error) || !vision::save_library(target, lib, error)) {
    reply.error(ErrorCode::StateFailed, error);
    return;
  }
  std::string old = config_.vision.library_path;
  config_.vision.library_path = target;
  if (!reload_vision(reply)) {
    config_.vision.library_path = old;
    return;
  }
  reply.result({{"taught", r.name}, {"index", r.index}, {"objects_in_library", lib.entries.size()}, {"library", target},
                {"area_px", round3(e.area_px)}, {"elongation", round3(e.elongation)},
                {"threshold", round3(e.threshold.value_or(0))}, {"warnings", warnings}});
}

}  // namespace rbx1::daemon
