// scene.hpp - the `scene` request: the arm's world as the console's 3D view draws it, in the base frame (mm): the
// URDF, the table, the places, the camera's view at the scan pose and the last scan's objects, each put where the
// camera-to-arm map in force (the workspace calibration, else [arm.camera]) puts it, by the pick's own functions.
#pragma once
#include <nlohmann/json.hpp>

#include "arm_config.hpp"

namespace rbx1::daemon {

// detections: the last scan's `rbx1 detect --json` document (null before the first scan).
nlohmann::json scene_json(const arm::ArmConfig& arm, const nlohmann::json& detections);

}  // namespace rbx1::daemon
