// pick_plan.hpp - from a detected object (rbx1 detect JSON) to firmware queue entries, through rbx1_arm's planner.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "arm_config.hpp"
#include "motion.hpp"

namespace rbx1::daemon {

// One move from the current position (STATUS) to a joint pose.
bool plan_pose_move(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const std::string& name,
                    const arm::Joints& pose, std::vector<MotionStep>& out, std::string& error);

// The whole pick of `object` (one element of the detection's "objects") to `place`. info gets the grasp in the
// base frame and the waypoints (the "planned" event). false + error (uncalibrated, infeasible grip, out of reach).
// image_size: the detection's frame (width, height), checked against the workspace calibration's.
bool plan_pick_steps(const arm::ArmConfig& cfg, const rbx1_status_resp& current, const nlohmann::json& object,
                     std::pair<int, int> image_size, const std::string& place, std::vector<MotionStep>& out, nlohmann::json& info, std::string& error);

}  // namespace rbx1::daemon
