// pick_plan.hpp - from a scanned object (vision::ScanObject) to firmware queue entries, through rbx1_arm's planner.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "arm_config.hpp"
#include "motion.hpp"
#include "types.hpp"

namespace rbx1::daemon {

// One move from the current position (STATUS) to a joint pose.
bool plan_pose_move(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const std::string& name,
                    const arm::Joints& pose, std::vector<MotionStep>& out, std::string& error);

// Where pixel px of the scan pose's frame lies on the table (base frame, mm), by the pick's own mapping: the
// workspace calibration's, else the camera mount's from the pixel's table centimetres (cm, none uncalibrated).
std::optional<Eigen::Vector2d> table_point(const arm::ArmConfig& cfg, cv::Point2d px, std::optional<cv::Point2d> cm);

// The pose that puts the camera's view centre over a point `shift` (mm, base frame) away from what it sees at the
// scan pose: the scan pose's tool moved by shift at the same height and yaw. false + error (out of reach).
bool look_pose(const arm::ArmConfig& cfg, const Eigen::Vector2d& shift, arm::Joints& out, std::string& error);

// The whole pick of `object` (one of the scan's objects) to `place`. info gets the grasp in the base frame and the
// waypoints (the "planned" event). false + error (uncalibrated, infeasible grip, out of reach).
// image_size: the scan's frame, checked against the workspace calibration's.
bool plan_pick_steps(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const vision::ScanObject& object,
                     cv::Size image_size, const std::string& place, std::vector<MotionStep>& out, nlohmann::json& info,
                     std::string& error);

}  // namespace rbx1::daemon
