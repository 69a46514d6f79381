// kinematics_test.cpp - FK at known poses, IK against FK over the workspace, the choice among solutions, limits.
#include "kinematics.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

#include "joint_steps.hpp"

using namespace rbx1::arm;

namespace {

double axis_diff(double a, double b) { return std::fabs(normalize_axis_deg(a - b)); }

}  // namespace

TEST(Kinematics, ForwardAtKnownPoses) {
  const Links l;  // 263, 221, 215, 120
  ToolPose up = tool_pose(l, Joints{0, 0, 0, 0, 0, 0});
  EXPECT_NEAR(up.x_mm, 0, 1e-9);
  EXPECT_NEAR(up.y_mm, 0, 1e-9);
  EXPECT_NEAR(up.z_mm, 819, 1e-9);
  EXPECT_NEAR(up.tilt_deg, 180, 1e-9);  // pointing straight up

  ToolPose level = tool_pose(l, Joints{0, 90, 0, 0, 0, 0});
  EXPECT_NEAR(level.x_mm, 556, 1e-9);
  EXPECT_NEAR(level.z_mm, 263, 1e-9);

  ToolPose left = tool_pose(l, Joints{90, 90, 0, 0, 0, 0});
  EXPECT_NEAR(left.x_mm, 0, 1e-9);
  EXPECT_NEAR(left.y_mm, 556, 1e-9);

  // Upper arm up, forearm level, wrist down: tool point 215 mm out, 120 mm below the forearm.
  ToolPose down = tool_pose(l, Joints{0, 0, 90, 0, 90, 0});
  EXPECT_NEAR(down.x_mm, 215, 1e-9);
  EXPECT_NEAR(down.z_mm, 263 + 221 - 120, 1e-9);
  EXPECT_NEAR(down.tilt_deg, 0, 1e-9);
  EXPECT_NEAR(down.yaw_deg, 0, 1e-9);
  // Top down, the closing line's yaw is J1 - J6 (mod 180).
  EXPECT_NEAR(axis_diff(tool_pose(l, Joints{30, 0, 90, 0, 90, -20}).yaw_deg, 50), 0, 1e-9);
  // The forearm roll turns the wrist's pitch plane: rolled 90 deg, pitching moves the tool sideways.
  ToolPose rolled = tool_pose(l, Joints{0, 0, 90, 90, 90, 0});
  EXPECT_NEAR(rolled.x_mm, 215, 1e-9);
  EXPECT_NEAR(std::fabs(rolled.y_mm), 120, 1e-9);
  EXPECT_NEAR(rolled.z_mm, 263 + 221, 1e-9);
}

TEST(Kinematics, IkMatchesFkOverTheWorkspace) {
  const ArmConfig c;
  const Joints home = c.home;
  double worst_mm = 0, worst_tilt = 0, worst_yaw = 0;
  double worst_q_mm = 0, worst_q_yaw = 0;  // after rounding to whole steps
  int solved = 0, rejected = 0;
  double solve_s = 0;
  for (double x = -400; x <= 450; x += 25) {
    for (double y = -450; y <= 450; y += 25) {
      for (double z : {-20.0, 0.0, 25.0, 60.0, 120.0, 200.0}) {
        for (double yaw : {-89.9, -60.0, -15.0, 0.0, 33.3, 75.0, 90.0}) {
          Grasp g{x, y, z, yaw};
          Joints q;
          std::string error;
          auto t0 = std::chrono::steady_clock::now();
          bool ok = ik(c, g, home, q, error);
          solve_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          if (!ok) {
            ++rejected;
            ASSERT_FALSE(error.empty());
            continue;
          }
          ++solved;
          std::string limit;
          ASSERT_TRUE(check_limits(c, q, limit)) << limit;
          ToolPose p = tool_pose(c.links, q);
          worst_mm = std::max(worst_mm, std::hypot(p.x_mm - x, p.y_mm - y, p.z_mm - z));
          worst_tilt = std::max(worst_tilt, p.tilt_deg);
          worst_yaw = std::max(worst_yaw, axis_diff(p.yaw_deg, yaw));
          ToolPose pq = tool_pose(c.links, steps_to_joints(c, joints_to_steps(c, q)));
          worst_q_mm = std::max(worst_q_mm, std::hypot(pq.x_mm - x, pq.y_mm - y, pq.z_mm - z));
          worst_q_yaw = std::max(worst_q_yaw, axis_diff(pq.yaw_deg, yaw));
        }
      }
    }
  }
  std::printf("IK round trip over %d solved grasps (%d rejected): worst %.3g mm, tilt %.3g deg, yaw %.3g deg; "
              "after rounding to steps: %.3f mm, yaw %.4f deg; %.2f us per IK\n",
              solved, rejected, worst_mm, worst_tilt, worst_yaw, worst_q_mm, worst_q_yaw,
              1e6 * solve_s / (solved + rejected));
  EXPECT_GT(solved, 10000);  // the grid covers the reachable table, not a corner of it
  EXPECT_GT(rejected, 1000); // and reaches past it
  EXPECT_LT(worst_mm, 0.1);
  EXPECT_LT(worst_tilt, 0.05);
  EXPECT_LT(worst_yaw, 0.05);
  // Whole steps: yaw is off by at most half a step of J6 (0.05625 deg) plus half a step of J1 (0.0053 deg).
  EXPECT_LT(worst_q_yaw, 0.062);
  EXPECT_LT(worst_q_mm, 0.15);
}

TEST(Kinematics, IkReturnsTheJointsFkCameFrom) {
  // Elbow-up, unflipped top-down poses within the limits: IK of their FK, starting there, gives them back.
  const ArmConfig c;
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int checked = 0;
  for (int i = 0; i < 5000 && checked < 1000; ++i) {
    Joints q{-120 + 240 * u(rng), -60 + 150 * u(rng), 1 + 119 * u(rng), 0, 0, -180 + 360 * u(rng)};
    q[4] = 180 - q[1] - q[2];
    std::string limit;
    if (!check_limits(c, q, limit)) continue;
    ToolPose p = tool_pose(c.links, q);
    ASSERT_NEAR(p.tilt_deg, 0, 1e-6);
    Joints back;
    std::string error;
    ASSERT_TRUE(ik(c, Grasp{p.x_mm, p.y_mm, p.z_mm, p.yaw_deg}, q, back, error)) << error;
    for (int j = 0; j < kJoints; ++j) ASSERT_NEAR(back[j], q[j], 1e-6) << "J" << j + 1 << " case " << i;
    ++checked;
  }
  EXPECT_EQ(checked, 1000);
}

TEST(Kinematics, SolutionsAreSortedElbowUpUnflippedNearest) {
  const ArmConfig c;
  std::vector<IkSolution> sols;
  std::string error;
  ASSERT_TRUE(ik_solutions(c, Grasp{300, 50, 20, 10}, c.home, sols, error)) << error;
  ASSERT_EQ(sols.size(), 8u);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(sols[i].elbow_up) << i;
  for (int i = 4; i < 8; ++i) EXPECT_FALSE(sols[i].elbow_up) << i;
  EXPECT_FALSE(sols[0].wrist_flipped);
  EXPECT_FALSE(sols[1].wrist_flipped);
  EXPECT_TRUE(sols[2].wrist_flipped);
  EXPECT_FALSE(sols[0].reaches_back);  // the front is nearer to home than leaning back over the base
  EXPECT_TRUE(sols[1].reaches_back);
  for (const IkSolution& s : sols) {
    ToolPose p = tool_pose(c.links, s.joints);
    EXPECT_NEAR(p.x_mm, 300, 1e-6);
    EXPECT_NEAR(p.y_mm, 50, 1e-6);
    EXPECT_NEAR(p.z_mm, 20, 1e-6);
    EXPECT_NEAR(axis_diff(p.yaw_deg, 10), 0, 1e-6);
    EXPECT_NEAR(p.tilt_deg, 0, 1e-6);
    // Elbow up: the elbow lies above the line from the shoulder to the wrist.
    Eigen::Vector3d shoulder(0, 0, c.links.base_height_mm);
    Eigen::Vector3d elbow = shoulder + Eigen::AngleAxisd(s.joints[0] * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                           Eigen::AngleAxisd(s.joints[1] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                                           Eigen::Vector3d(0, 0, c.links.upper_arm_mm);
    Eigen::Vector3d wrist(300, 50, 20 + c.links.tool_mm);
    Eigen::Vector2d wrist_xy(wrist.x(), wrist.y());
    double t = Eigen::Vector2d(elbow.x(), elbow.y()).dot(wrist_xy) / wrist_xy.squaredNorm();  // signed
    double line_z = shoulder.z() + t * (wrist.z() - shoulder.z());
    if (!s.reaches_back) {
      EXPECT_EQ(elbow.z() > line_z, s.elbow_up);
    }
  }
  Joints q;
  ASSERT_TRUE(ik(c, Grasp{300, 50, 20, 10}, c.home, q, error));
  EXPECT_EQ(q, sols[0].joints);
  EXPECT_DOUBLE_EQ(q[3], 0.0);
  EXPECT_GT(q[2], 0.0);  // front, elbow up: the elbow bends forward
}

TEST(Kinematics, WristRollNearestToTheCurrentOne) {
  // The gripper is symmetric under 180 deg: yaw 0 at (300, 0) is J6 = 0 or +-180; the current J6 decides.
  const ArmConfig c;
  Joints q;
  std::string error;
  Joints current = c.home;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 0}, current, q, error)) << error;
  EXPECT_NEAR(q[5], 0, 1e-9);
  current[5] = 170;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 0}, current, q, error)) << error;
  EXPECT_NEAR(q[5], 180, 1e-9);
  current[5] = -100;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 0}, current, q, error)) << error;
  EXPECT_NEAR(q[5], -180, 1e-9);
  // Yaw 100 = yaw -80: J6 = J1 - yaw + k * 180 = -100 or 80, whichever is nearer.
  current[5] = 0;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 100}, current, q, error)) << error;
  EXPECT_NEAR(q[5], 80, 1e-9);
  current[5] = -120;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 100}, current, q, error)) << error;
  EXPECT_NEAR(q[5], -100, 1e-9);
  // Only equivalents within the wrist's range count.
  ArmConfig narrow;
  narrow.joints[5].min_deg = -90;
  narrow.joints[5].max_deg = 90;
  current[5] = -89;
  ASSERT_TRUE(ik(narrow, Grasp{300, 0, 20, 100}, current, q, error)) << error;
  EXPECT_NEAR(q[5], 80, 1e-9);
}

TEST(Kinematics, BehindTheBaseLeansBack) {
  // J1 cannot turn to 180 (limit 120): the arm keeps J1 = 0 and leans back over the base.
  const ArmConfig c;
  Joints q;
  std::string error;
  ASSERT_TRUE(ik(c, Grasp{-250, 0, 50, 0}, c.home, q, error)) << error;
  EXPECT_NEAR(q[0], 0, 1e-9);
  EXPECT_LT(q[1], 0);
  ToolPose p = tool_pose(c.links, q);
  EXPECT_NEAR(p.x_mm, -250, 1e-6);
  EXPECT_NEAR(p.z_mm, 50, 1e-6);
}

TEST(Kinematics, FlippedWristOnlyWhenTheUnflippedOneIsOutOfLimits) {
  ArmConfig c;
  c.joints[4].min_deg = -115;  // the wrist pitch can only bend backwards
  c.joints[4].max_deg = -1;
  Joints q;
  std::string error;
  ASSERT_TRUE(ik(c, Grasp{300, 0, 20, 30}, c.home, q, error)) << error;
  EXPECT_NEAR(std::fabs(q[3]), 180, 1e-9);
  EXPECT_LT(q[4], 0);
  ToolPose p = tool_pose(c.links, q);
  EXPECT_NEAR(p.x_mm, 300, 1e-6);
  EXPECT_NEAR(p.z_mm, 20, 1e-6);
  EXPECT_NEAR(axis_diff(p.yaw_deg, 30), 0, 1e-6);
}

TEST(Kinematics, LimitsRejectedNamingTheJoint) {
  const ArmConfig c;
  std::string error;
  EXPECT_TRUE(check_limits(c, c.home, error));
  EXPECT_FALSE(check_limits(c, Joints{0, 0, 130, 0, 0, 0}, error));
  EXPECT_EQ(error, "J3 (elbow) at 130.00 deg is above its limit max_deg = 120 (arm.joints.j3.max_deg)");
  EXPECT_FALSE(check_limits(c, Joints{-121, 0, 0, 0, 0, 0}, error));
  EXPECT_EQ(error, "J1 (base yaw) at -121.00 deg is below its limit min_deg = -120 (arm.joints.j1.min_deg)");

  ArmConfig tight;
  tight.joints[4].min_deg = 20;  // the wrist cannot stay nearly straight, as a far target needs
  tight.joints[3].min_deg = -90;  // nor roll half a turn to flip
  tight.joints[3].max_deg = 90;
  Joints q;
  EXPECT_FALSE(ik(tight, Grasp{250, 0, 0, 0}, tight.home, q, error));
  EXPECT_EQ(error.rfind("no elbow-up solution within the joint limits: J5 (wrist pitch) at ", 0), 0u) << error;
  EXPECT_NE(error.find("below its limit min_deg = 20 (arm.joints.j5.min_deg)"), std::string::npos) << error;
}

TEST(Kinematics, OutOfReach) {
  const ArmConfig c;
  Joints q;
  std::string error;
  EXPECT_FALSE(ik(c, Grasp{600, 0, 0, 0}, c.home, q, error));
  EXPECT_EQ(error,
            "target (600.0, 0.0, 0.0) mm is out of reach: the wrist would be 616.8 mm from the shoulder, "
            "the arm reaches 436.0 mm");
}

TEST(Kinematics, NonFiniteInputsAreRejected) {
  const ArmConfig c;
  Joints q;
  std::string error;
  EXPECT_FALSE(ik(c, Grasp{NAN, 0, 0, 0}, c.home, q, error));
  EXPECT_EQ(error, "target has a coordinate or yaw that is not a finite number");
  EXPECT_FALSE(ik(c, Grasp{300, 0, 0, INFINITY}, c.home, q, error));
  EXPECT_FALSE(check_limits(c, Joints{0, 0, NAN, 0, 0, 0}, error));
  EXPECT_EQ(error, "J3 (elbow) has no finite angle");
}

TEST(Kinematics, Normalisation) {
  EXPECT_DOUBLE_EQ(normalize_deg(180), 180);
  EXPECT_DOUBLE_EQ(normalize_deg(-180), 180);
  EXPECT_DOUBLE_EQ(normalize_deg(370), 10);
  EXPECT_DOUBLE_EQ(normalize_axis_deg(90), 90);
  EXPECT_DOUBLE_EQ(normalize_axis_deg(-90), 90);
  EXPECT_DOUBLE_EQ(normalize_axis_deg(135), -45);
  EXPECT_DOUBLE_EQ(normalize_axis_deg(-100), 80);
}

TEST(Kinematics, StandardDhTableOfTheReadmeGivesTheSameChain) {
  // README: theta = (q1, q2 - 90, q3 + 90, q4, q5, q6), d = (base, 0, 0, forearm, 0, tool),
  // a = (0, upper_arm, 0, 0, 0, 0), alpha = (-90, 0, 90, -90, 90, 0); T_i = Rz(theta) Tz(d) Tx(a) Rx(alpha).
  const Links l;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-180.0, 180.0);
  auto r = [](double d) { return d * M_PI / 180; };
  for (int n = 0; n < 200; ++n) {
    Joints q{u(rng), u(rng), u(rng), u(rng), u(rng), u(rng)};
    const double theta[6] = {q[0], q[1] - 90, q[2] + 90, q[3], q[4], q[5]};
    const double d[6] = {l.base_height_mm, 0, 0, l.forearm_mm, 0, l.tool_mm};
    const double a[6] = {0, l.upper_arm_mm, 0, 0, 0, 0};
    const double alpha[6] = {-90, 0, 90, -90, 90, 0};
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 6; ++i) {
      t.rotate(Eigen::AngleAxisd(r(theta[i]), Eigen::Vector3d::UnitZ()));
      t.translate(Eigen::Vector3d(a[i], 0, d[i]));
      t.rotate(Eigen::AngleAxisd(r(alpha[i]), Eigen::Vector3d::UnitX()));
    }
    ASSERT_TRUE(t.matrix().isApprox(fk(l, q).matrix(), 1e-12)) << n;
  }
}
