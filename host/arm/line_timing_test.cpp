// line_timing_test.cpp - the look-ahead model's time against closed forms, and a line's durations: at the limits
// when the line is slower than a joint move's pace, stretched to the pace otherwise, never above a joint's limit.
#include "line_timing.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "joint_steps.hpp"
#include "line.hpp"
#include "pick.hpp"

using namespace rbx1::arm;

// One segment from rest to rest: a trapezoid from and to the stop rate v0 = sqrt(a / 2), cruising at the limit.
TEST(LineTiming, OneSegmentIsTheFirmwaresTrapezoid) {
  const ArmConfig c;  // 4000 steps/s, 8000 steps/s^2
  const double v0 = std::sqrt(4000.0);
  // Ramps from v0 to 4000 over (4000^2 - v0^2) / 8000 steps each, 8000 - 2 * that at 4000 steps/s.
  const double ramp = (16e6 - v0 * v0) / 16000, expected = 2 * (4000 - v0) / 8000 + (8000 - 2 * ramp) / 4000;
  EXPECT_NEAR(stream_seconds(c, Steps{}, {Steps{0, 0, 8000, 0, 0, 0}}, {1e9}), expected, 1e-9);
  // A cap of 2000 steps/s: cruise at the cap.
  const double r2 = (4e6 - v0 * v0) / 16000, e2 = 2 * (2000 - v0) / 8000 + (8000 - 2 * r2) / 2000;
  EXPECT_NEAR(stream_seconds(c, Steps{}, {Steps{0, 0, 8000, 0, 0, 0}}, {2000}), e2, 1e-9);
  // Too short to cruise: a triangle peaking at sqrt(v0^2 + 2 a n / 2).
  const double vp = std::sqrt(v0 * v0 + 2 * 8000.0 * 500);
  EXPECT_NEAR(stream_seconds(c, Steps{}, {Steps{0, 0, 1000, 0, 0, 0}}, {1e9}), 2 * (vp - v0) / 8000, 1e-9);
  // A joint moving half as far as the dominant one sees half the rate: J2 limited to 1000 caps the dominant at 2000.
  ArmConfig slow = c;
  slow.joints[1].max_speed_steps_s = 1000;
  EXPECT_NEAR(stream_seconds(slow, Steps{}, {Steps{0, 4000, 8000, 0, 0, 0}}, {1e9}), e2, 1e-9);
}

// Two collinear segments run on as one; a reversal between them stops.
TEST(LineTiming, JunctionsJoinOrStop) {
  const ArmConfig c;
  const double one = stream_seconds(c, Steps{}, {Steps{0, 0, 8000, 0, 0, 0}}, {1e9});
  EXPECT_NEAR(stream_seconds(c, Steps{}, {Steps{0, 0, 3000, 0, 0, 0}, Steps{0, 0, 8000, 0, 0, 0}}, {1e9, 1e9}), one,
              1e-9);
  const double there = stream_seconds(c, Steps{}, {Steps{0, 0, 4000, 0, 0, 0}}, {1e9});
  EXPECT_NEAR(stream_seconds(c, Steps{}, {Steps{0, 0, 4000, 0, 0, 0}, Steps{}}, {1e9, 1e9}), 2 * there, 1e-9);
}

// The pick's lines: each at the joints' limits (fastest) or stretched to a joint move's pace, whichever is slower;
// the durations sent give back that time (planned_s) and no segment asks a joint for more than its limit allows.
TEST(LineTiming, LinesKeepTheSlowerOfTheLimitsAndThePace) {
  for (double speed : {5.0, 20.0, 90.0}) {
    ArmConfig c;
    c.speeds.joint_speed_deg_s = speed;
    const Steps start = scan_steps(c);
    const ToolPose p = tool_pose(c.links, steps_to_joints(c, start));
    std::vector<Steps> targets;
    std::string error;
    ASSERT_TRUE(plan_line(c, start, Grasp{p.x_mm, p.y_mm, p.z_mm, p.yaw_deg},
                          Grasp{330.0, -60.0, 70.0, p.yaw_deg}, LineBounds{}, targets, error))
        << error;
    LineTiming t;
    ASSERT_TRUE(time_line(c, start, targets, t, error)) << error;
    ASSERT_EQ(t.duration_ms.size(), targets.size());
    EXPECT_NEAR(t.planned_s, std::max(t.fastest_s, t.pace_s), 0.01 * t.planned_s) << speed;
    EXPECT_GT(t.pace_s, 0.2);
    Steps at = start;
    for (size_t k = 0; k < targets.size(); ++k) {
      for (int j = 0; j < kJoints; ++j) {
        // The rate the duration asks of the joint, against its limit (at the limits the duration is rounded down:
        // the firmware's limit rules there, within one millisecond).
        const double rate = std::abs(targets[k][j] - at[j]) / (t.duration_ms[k] * 1e-3);
        const double slack = std::abs(targets[k][j] - at[j]) / (t.duration_ms[k] * 1e-3) -
                             std::abs(targets[k][j] - at[j]) / ((t.duration_ms[k] + 1) * 1e-3);
        EXPECT_LE(rate, c.joints[j].max_speed_steps_s + slack + 1e-9) << speed << " segment " << k << " J" << j + 1;
      }
      at = targets[k];
    }
  }
  // Slow pace: stretched to it; fast: at the limits.
  ArmConfig slow;
  slow.speeds.joint_speed_deg_s = 5;
  ArmConfig fast;
  fast.speeds.joint_speed_deg_s = 90;
  const Steps start = scan_steps(slow);
  const ToolPose p = tool_pose(slow.links, steps_to_joints(slow, start));
  std::vector<Steps> targets;
  std::string error;
  ASSERT_TRUE(plan_line(slow, start, Grasp{p.x_mm, p.y_mm, p.z_mm, p.yaw_deg}, Grasp{330.0, -60.0, 70.0, p.yaw_deg},
                        LineBounds{}, targets, error));
  LineTiming ts, tf;
  ASSERT_TRUE(time_line(slow, start, targets, ts, error));
  ASSERT_TRUE(time_line(fast, start, targets, tf, error));
  EXPECT_GT(ts.pace_s, ts.fastest_s);
  EXPECT_NEAR(ts.planned_s, ts.pace_s, 0.005 * ts.pace_s);
  EXPECT_LT(tf.pace_s, tf.fastest_s);
  EXPECT_NEAR(tf.planned_s, tf.fastest_s, 0.005 * tf.fastest_s);
}
