// vision_map_test.cpp - perception's table cm and grip angles into the arm base frame for known mounts.
#include "vision_map.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace rbx1::arm;

TEST(VisionMap, IdentityMountScalesCmToMm) {
  ArmConfig c;
  c.camera = CameraMount{0, 0, 0, false};
  c.heights.table_z_mm = -7;
  TablePoint t = vision_to_base(c, Eigen::Vector2d(1.5, 2.0), 30);
  EXPECT_NEAR(t.x_mm, 15, 1e-9);
  EXPECT_NEAR(t.y_mm, 20, 1e-9);
  EXPECT_DOUBLE_EQ(t.z_mm, -7);
  EXPECT_NEAR(t.yaw_deg, 30, 1e-9);
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(0, 0), 120).yaw_deg, -60, 1e-9);  // an axis: 120 = -60
}

TEST(VisionMap, DefaultMountLooksForwardWithImageRightToTheArmsRight) {
  const ArmConfig c;  // origin (370, 100), rotation -90, y mirrored
  TablePoint corner = vision_to_base(c, Eigen::Vector2d(0, 0), 0);
  EXPECT_NEAR(corner.x_mm, 370, 1e-9);
  EXPECT_NEAR(corner.y_mm, 100, 1e-9);
  TablePoint centre = vision_to_base(c, Eigen::Vector2d(10, 7.5), 0);
  EXPECT_NEAR(centre.x_mm, 295, 1e-9);
  EXPECT_NEAR(centre.y_mm, 0, 1e-9);
  // Image right (+x) is base -y: an axis at 90. Image down (+y) is base -x: an axis at 0.
  EXPECT_NEAR(centre.yaw_deg, 90, 1e-9);
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(10, 7.5), 90).yaw_deg, 0, 1e-9);
  // Right and down on screen (+45 deg, clockwise) is -x -y in the base frame: the axis at 45.
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(10, 7.5), 45).yaw_deg, 45, 1e-9);
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(10, 7.5), -50).yaw_deg, -40, 1e-9);
  TablePoint far_right = vision_to_base(c, Eigen::Vector2d(20, 0), 0);
  EXPECT_NEAR(far_right.x_mm, 370, 1e-9);
  EXPECT_NEAR(far_right.y_mm, -100, 1e-9);
}

TEST(VisionMap, RotatedMirroredAndOffset) {
  ArmConfig c;
  c.camera = CameraMount{100, -50, 30, true};
  const double a = 30 * M_PI / 180;
  // p = (2, 3) cm -> F p = (20, -30) mm -> R(30) -> + origin.
  TablePoint t = vision_to_base(c, Eigen::Vector2d(2, 3), 10);
  EXPECT_NEAR(t.x_mm, 100 + 20 * std::cos(a) + 30 * std::sin(a), 1e-9);
  EXPECT_NEAR(t.y_mm, -50 + 20 * std::sin(a) - 30 * std::cos(a), 1e-9);
  // Mirroring negates the angle, the rotation adds to it: -10 + 30.
  EXPECT_NEAR(t.yaw_deg, 20, 1e-9);
  c.camera.flip_y = false;
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(2, 3), 10).yaw_deg, 40, 1e-9);
  EXPECT_NEAR(vision_to_base(c, Eigen::Vector2d(2, 3), 70).yaw_deg, -80, 1e-9);
}
