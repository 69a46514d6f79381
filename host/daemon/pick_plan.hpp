// pick_plan.hpp - from a scanned object (vision::ScanObject) to firmware queue entries, through rbx1_arm's planner.
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "arm_config.hpp"
#include "motion.hpp"
#include "types.hpp"

namespace rbx1::daemon {

// One move from the current position (STATUS) to a joint pose.
bool plan_pose_move(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const std::string& name,
                    const arm::Joints& pose, std::vector<MotionStep>& out, std::string& error);

// The whole pick of `object` (one of the scan's objects) to `place`. info gets the grasp in the base frame and the
// waypoints (the "planned" event). false + error (uncalibrated, infeasible grip, out of reach).
// image_size: the scan's frame, checked against the workspace calibration's.
bool plan_pick_steps(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const vision::ScanObject& object,
                     cv::Size image_size, const std::string& place, std::vector<MotionStep>& out, nlohmann::json& info,
                     std::string& error);

}  // namespace rbx1::daemon
