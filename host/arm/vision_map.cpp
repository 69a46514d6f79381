// vision_map.cpp - the camera mount's planar transform: rotation, optional mirror of the image y axis, offset.
#include "vision_map.hpp"

#include <numbers>
#include <cmath>

#include "kinematics.hpp"

namespace rbx1::arm {

TablePoint vision_to_base(const ArmConfig& cfg, const Eigen::Vector2d& centroid_cm, double grip_angle_deg) {
  const CameraMount& m = cfg.camera;
  const double rot = m.rotation_deg * std::numbers::pi / 180.0;
  Eigen::Matrix2d r;
  r << std::cos(rot), -std::sin(rot), std::sin(rot), std::cos(rot);
  Eigen::Matrix2d a = r * Eigen::Vector2d(1.0, m.flip_y ? -1.0 : 1.0).asDiagonal();
  Eigen::Vector2d p = Eigen::Vector2d(m.origin_x_mm, m.origin_y_mm) + a * (10.0 * centroid_cm);
  const double g = grip_angle_deg * std::numbers::pi / 180.0;
  Eigen::Vector2d dir = a * Eigen::Vector2d(std::cos(g), std::sin(g));
  TablePoint t;
  t.x_mm = p.x();
  t.y_mm = p.y();
  t.z_mm = cfg.heights.table_z_mm;
  t.yaw_deg = normalize_axis_deg(std::atan2(dir.y(), dir.x()) * 180.0 / std::numbers::pi);
  return t;
}

TablePoint pixels_to_base(const ArmConfig& cfg, const Eigen::Vector2d& centroid_px, const Eigen::Vector2d& p1_px,
                          const Eigen::Vector2d& p2_px, double& opening_mm) {
  const auto& m = *cfg.camera.pixel_map;
  Eigen::Matrix3d h;
  h << m.h[0], m.h[1], m.h[2], m.h[3], m.h[4], m.h[5], m.h[6], m.h[7], m.h[8];
  auto map = [&h](const Eigen::Vector2d& p) { return (h * p.homogeneous()).hnormalized(); };
  Eigen::Vector2d c = map(centroid_px), a = map(p1_px), b = map(p2_px);
  opening_mm = (b - a).norm();
  TablePoint t;
  t.x_mm = c.x();
  t.y_mm = c.y();
  t.z_mm = cfg.heights.table_z_mm;
  t.yaw_deg = normalize_axis_deg(std::atan2(b.y() - a.y(), b.x() - a.x()) * 180.0 / std::numbers::pi);
  return t;
}

}  // namespace rbx1::arm
