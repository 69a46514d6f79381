// joint_steps_test.cpp - exact step counts for known angles, the rounding rule, and both round trips.
#include "joint_steps.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace rbx1::arm;

TEST(JointSteps, KnownAnglesGiveKnownCounts) {
  const ArmConfig c;
  // 200 x 16 x reduction steps per joint turn: 34144, 16000, 68800, 3200, 14944, 3200.
  EXPECT_EQ(angle_to_steps(c.joints[0], 90.0), 8536);
  EXPECT_EQ(angle_to_steps(c.joints[1], 90.0), 4000);
  EXPECT_EQ(angle_to_steps(c.joints[2], 90.0), 17200);
  EXPECT_EQ(angle_to_steps(c.joints[3], 90.0), 800);
  EXPECT_EQ(angle_to_steps(c.joints[4], 90.0), 3736);
  EXPECT_EQ(angle_to_steps(c.joints[5], -90.0), -800);
  EXPECT_EQ(angle_to_steps(c.joints[0], 1.0), 95);     // 94.84
  EXPECT_EQ(angle_to_steps(c.joints[0], -1.0), -95);
  EXPECT_EQ(angle_to_steps(c.joints[4], 120.0), 4981); // 4981.33
  EXPECT_EQ(angle_to_steps(c.joints[2], 50.0), 9556);  // 9555.56
  EXPECT_EQ(joints_to_steps(c, c.scan), (Steps{0, 889, 11467, 0, 4151, 0}));  // 888.89, 11466.67, 4151.11
  EXPECT_DOUBLE_EQ(steps_per_rev(c.joints[2]), 68800.0);
}

TEST(JointSteps, HalvesRoundAwayFromZero) {
  JointConfig j;  // 360 steps per turn: one step per degree, so half-degree angles are exact ties
  j.motor_steps = 360;
  j.microsteps = 1;
  j.reduction = 1;
  EXPECT_EQ(angle_to_steps(j, 0.5), 1);
  EXPECT_EQ(angle_to_steps(j, 2.5), 3);
  EXPECT_EQ(angle_to_steps(j, -0.5), -1);
  EXPECT_EQ(angle_to_steps(j, -2.5), -3);
  EXPECT_EQ(angle_to_steps(j, 2.49), 2);
  EXPECT_EQ(angle_to_steps(j, -2.51), -3);
}

TEST(JointSteps, DirectionAndZeroOffset) {
  JointConfig j;
  j.motor_steps = 200;
  j.microsteps = 16;
  j.reduction = 5;  // 16000 steps per turn
  j.direction = -1;
  j.zero_deg = -90;
  EXPECT_EQ(angle_to_steps(j, -90.0), 0);
  EXPECT_EQ(angle_to_steps(j, 0.0), -4000);
  EXPECT_DOUBLE_EQ(steps_to_angle(j, -4000), 0.0);
  EXPECT_DOUBLE_EQ(steps_to_angle(j, 8000), -270.0);
}

TEST(JointSteps, StepsToAnglesToStepsIsTheIdentity) {
  ArmConfig c;
  c.joints[1].direction = -1;
  c.joints[2].zero_deg = 37.5;
  for (int j = 0; j < kJoints; ++j) {
    for (int32_t s = -200000; s <= 200000; s += 997) {
      ASSERT_EQ(angle_to_steps(c.joints[j], steps_to_angle(c.joints[j], s)), s) << "J" << j + 1;
    }
  }
}

TEST(JointSteps, AnglesToStepsToAnglesWithinHalfAStep) {
  ArmConfig c;
  c.joints[4].direction = -1;
  for (int j = 0; j < kJoints; ++j) {
    const double half_step = 180.0 / steps_per_rev(c.joints[j]);
    double worst = 0;
    for (double a = c.joints[j].min_deg; a <= c.joints[j].max_deg; a += 0.0137) {
      double back = steps_to_angle(c.joints[j], angle_to_steps(c.joints[j], a));
      worst = std::max(worst, std::fabs(back - a));
    }
    EXPECT_LE(worst, half_step + 1e-12) << "J" << j + 1;
    EXPECT_GT(worst, 0.9 * half_step) << "J" << j + 1;  // the grid does land near half-step angles
  }
  Joints q{12.3, -45.6, 78.9, -101.1, 33.3, 179.0};
  Joints back = steps_to_joints(c, joints_to_steps(c, q));
  for (int j = 0; j < kJoints; ++j) EXPECT_NEAR(back[j], q[j], 180.0 / steps_per_rev(c.joints[j]));
}
