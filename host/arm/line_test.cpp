// line_test.cpp - straight lines: every segment's joint-linear path, sampled densely with FK, stays within the
// stated bounds of the line; the ends are where asked; the checker itself catches a path that bows.
#include "line.hpp"

#include <gtest/gtest.h>

#include "joint_steps.hpp"

using namespace rbx1::arm;

namespace {

constexpr int kDense = 200;  // FK samples per segment in the checks (the planner uses 16)

Steps start_of(const ArmConfig& cfg, const Grasp& g) {
  Joints q{};
  std::string error;
  EXPECT_TRUE(ik(cfg, g, cfg.scan, q, error)) << error;
  return joints_to_steps(cfg, q);
}

// Plans from -> to and checks every segment densely; returns the number of segments.
size_t check_line(const ArmConfig& cfg, const Grasp& from, const Grasp& to) {
  LineBounds b;
  Steps start = start_of(cfg, from);
  std::vector<Steps> out;
  std::string error;
  EXPECT_TRUE(plan_line(cfg, start, from, to, b, out, error)) << error;
  Steps a = start;
  LineError worst;
  for (const Steps& s : out) {
    LineError e = line_error(cfg, a, s, from, to, kDense);
    worst.deviation_mm = std::max(worst.deviation_mm, e.deviation_mm);
    worst.yaw_deg = std::max(worst.yaw_deg, e.yaw_deg);
    worst.tilt_deg = std::max(worst.tilt_deg, e.tilt_deg);
    a = s;
  }
  EXPECT_LE(worst.deviation_mm, b.deviation_mm);
  EXPECT_LE(worst.yaw_deg, b.yaw_deg);
  EXPECT_LE(worst.tilt_deg, b.tilt_deg);
  ToolPose end = tool_pose(cfg.links, steps_to_joints(cfg, out.back()));
  EXPECT_NEAR(end.x_mm, to.x_mm, 0.2);
  EXPECT_NEAR(end.y_mm, to.y_mm, 0.2);
  EXPECT_NEAR(end.z_mm, to.z_mm, 0.2);
  return out.size();
}

}  // namespace

TEST(Line, VerticalDescendAndLiftStayOnTheLine) {
  ArmConfig cfg;
  for (auto [x, y, yaw] : {std::tuple{300.0, 0.0, 0.0}, {250.0, 120.0, 35.0}, {200.0, -180.0, -70.0},
                           {380.0, 60.0, 89.0}}) {
    Grasp above{x, y, 80.0, yaw}, grasp{x, y, 17.0, yaw};
    size_t n = check_line(cfg, above, grasp);
    EXPECT_GE(n, 1u);
    EXPECT_LE(n, 64u);
    check_line(cfg, grasp, Grasp{x, y, 120.0, yaw});  // lift
  }
}

TEST(Line, SlantedApproachWithAYawChange) {
  ArmConfig cfg;
  ToolPose scan = tool_pose(cfg.links, cfg.scan);
  Grasp from{scan.x_mm, scan.y_mm, scan.z_mm, scan.yaw_deg};
  size_t n = check_line(cfg, from, Grasp{220.0, 150.0, 60.0, 40.0});
  EXPECT_GT(n, 4u);  // a long slanted line needs many segments for 0.2 mm
}

TEST(Line, CheckerSeesTheBowOfASingleJointMove) {
  ArmConfig cfg;
  Grasp from{350.0, -150.0, 60.0, 0.0}, to{350.0, 150.0, 60.0, 0.0};
  Steps a = start_of(cfg, from), b = start_of(cfg, to);
  LineError e = line_error(cfg, a, b, from, to, kDense);
  EXPECT_GT(e.deviation_mm, 5.0);  // the base turns: the tool point sweeps an arc, far off the chord
}

TEST(Line, OutOfReachIsAnError) {
  ArmConfig cfg;
  Grasp from{300.0, 0.0, 80.0, 0.0};
  std::vector<Steps> out;
  std::string error;
  EXPECT_FALSE(plan_line(cfg, start_of(cfg, from), from, Grasp{1500.0, 0.0, 80.0, 0.0}, LineBounds{}, out, error));
  EXPECT_NE(error.find("out of reach"), std::string::npos) << error;
}
