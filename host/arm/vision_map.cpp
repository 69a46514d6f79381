// vision_map.cpp - the camera mount's planar transform: rotation, optional mirror of the image y axis, offset.
#include "vision_map.hpp"

#include <cmath>

#include "kinematics.hpp"

namespace rbx1::arm {

TablePoint vision_to_base(const ArmConfig& cfg, const Eigen::Vector2d& centroid_cm, double grip_angle_deg) {
  constexpr double kPi = 3.14159265358979323846;
  const CameraMount& m = cfg.camera;
  const double rot = m.rotation_deg * kPi / 180.0;
  Eigen::Matrix2d r;
  r << std::cos(rot), -std::sin(rot), std::sin(rot), std::cos(rot);
  Eigen::Matrix2d a = r * Eigen::Vector2d(1.0, m.flip_y ? -1.0 : 1.0).asDiagonal();
  Eigen::Vector2d p = Eigen::Vector2d(m.origin_x_mm, m.origin_y_mm) + a * (10.0 * centroid_cm);
  const double g = grip_angle_deg * kPi / 180.0;
  Eigen::Vector2d dir = a * Eigen::Vector2d(std::cos(g), std::sin(g));
  TablePoint t;
  t.x_mm = p.x();
  t.y_mm = p.y();
  t.z_mm = cfg.heights.table_z_mm;
  t.yaw_deg = normalize_axis_deg(std::atan2(dir.y(), dir.x()) * 180.0 / kPi);
  return t;
}

}  // namespace rbx1::arm
