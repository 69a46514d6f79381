// vision_map.hpp - perception's table coordinates (cm, image axes) to the arm base frame (mm) at the scan pose.
#pragma once
#include <Eigen/Core>

#include "arm_config.hpp"

namespace rbx1::arm {

// A point on the table in the arm base frame and the gripper's closing-line yaw there, folded into (-90, 90].
struct TablePoint {
  double x_mm = 0, y_mm = 0, z_mm = 0, yaw_deg = 0;
};

// centroid_cm and grip_angle_deg as `rbx1 detect --json` reports them (objects[].centroid_cm, grip.angle_deg):
// base = origin + R(rotation) * F * 10 * centroid_cm (CameraMount); the angle's direction maps through R * F.
// z_mm is the table surface (heights.table_z_mm).
TablePoint vision_to_base(const ArmConfig& cfg, const Eigen::Vector2d& centroid_cm, double grip_angle_deg);

// Through the workspace calibration (cfg.camera.pixel_map, which must be set): the centroid and the grip's contact
// points in undistorted pixels (objects[].centroid_px, grip.p1_px, grip.p2_px) -> the grasp point, the closing
// line's yaw and the opening (mm, the contact points' distance on the table).
TablePoint pixels_to_base(const ArmConfig& cfg, const Eigen::Vector2d& centroid_px, const Eigen::Vector2d& p1_px,
                          const Eigen::Vector2d& p2_px, double& opening_mm);

}  // namespace rbx1::arm
