// pick_test.cpp - the pick's waypoints: phases in order, kinds, heights, yaw, gripper pulses, timing, the straight
// lines (checked with FK, independently of line.cpp) and errors.
#include "pick.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "vision_map.hpp"

using namespace rbx1::arm;

namespace {

double axis_diff(double a, double b) { return std::fabs(normalize_axis_deg(a - b)); }

const char* const kNames[] = {"approach", "yaw",   "open",    "descend", "close",
                              "lift",     "carry", "release", "retreat", "home"};

// The phases in order (consecutive waypoints of one name are one phase) and each phase's last waypoint.
std::vector<std::string> phases(const std::vector<Waypoint>& w) {
  std::vector<std::string> out;
  for (const auto& x : w)
    if (out.empty() || out.back() != x.name) out.push_back(x.name);
  return out;
}
const Waypoint& last(const std::vector<Waypoint>& w, const std::string& name) {
  for (size_t i = w.size(); i-- > 0;)
    if (w[i].name == name) return w[i];
  ADD_FAILURE() << "no waypoint " << name;
  return w.front();
}
size_t count(const std::vector<Waypoint>& w, const std::string& name) {
  size_t n = 0;
  for (const auto& x : w) n += x.name == name;
  return n;
}

}  // namespace

TEST(Gripper, OpeningToPulse) {
  GripperConfig g;  // 1000 us closed, 2000 us at 50 mm
  uint16_t us = 0;
  std::string error;
  ASSERT_TRUE(gripper_pulse_us(g, 0, us, error));
  EXPECT_EQ(us, 1000);
  ASSERT_TRUE(gripper_pulse_us(g, 25, us, error));
  EXPECT_EQ(us, 1500);
  ASSERT_TRUE(gripper_pulse_us(g, 50, us, error));
  EXPECT_EQ(us, 2000);
  ASSERT_TRUE(gripper_pulse_us(g, 12.3, us, error));
  EXPECT_EQ(us, 1246);
  EXPECT_FALSE(gripper_pulse_us(g, 50.5, us, error));
  EXPECT_EQ(error, "gripper opening 50.5 mm is wider than the gripper's 50.0 mm (arm.gripper.max_opening_mm)");
  EXPECT_FALSE(gripper_pulse_us(g, 50.04, us, error));  // within the first decimal: two of them
  EXPECT_EQ(error, "gripper opening 50.04 mm is wider than the gripper's 50.00 mm (arm.gripper.max_opening_mm)");
  EXPECT_FALSE(gripper_pulse_us(g, -1, us, error));
  g.closed_us = 2000;  // a servo mounted the other way round
  g.open_us = 1000;
  ASSERT_TRUE(gripper_pulse_us(g, 10, us, error));
  EXPECT_EQ(us, 1800);
}

TEST(Pick, HomeAndScanSteps) {
  const ArmConfig c;
  EXPECT_EQ(home_steps(c), (Steps{0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(scan_steps(c), (Steps{0, 889, 11467, 0, 4151, 0}));
}

TEST(Pick, MoveDuration) {
  const ArmConfig c;  // 20 deg/s, at least 200 ms
  EXPECT_EQ(move_duration_ms(c, Joints{}, Joints{0, 20, -10, 0, 0, 0}), 1000);
  EXPECT_EQ(move_duration_ms(c, Joints{}, Joints{0, 0, 0, 0, 0, 30.01}), 1501);
  EXPECT_EQ(move_duration_ms(c, Joints{}, Joints{0, 1, 0, 0, 0, 0}), 200);
  Waypoint w;
  std::string error;
  ASSERT_TRUE(plan_move(c, "scan", home_steps(c), c.scan, w, error)) << error;
  EXPECT_EQ(w.steps, scan_steps(c));
  EXPECT_EQ(w.duration_ms, 5000);  // J5 turns 4151 steps = 99.9973 deg
  EXPECT_FALSE(plan_move(c, "scan", home_steps(c), Joints{0, 0, 0, 0, 120, 0}, w, error));
  EXPECT_EQ(error, "scan: J5 (wrist pitch) at 120.00 deg is above its limit max_deg = 115 (arm.joints.j5.max_deg)");
  ArmConfig slow;
  slow.speeds.joint_speed_deg_s = 1;
  EXPECT_FALSE(plan_move(slow, "scan", home_steps(c), c.scan, w, error));
  EXPECT_EQ(error.rfind("scan: the move would take 99998 ms", 0), 0u) << error;
}

TEST(Pick, WaypointsInOrderWithTheirContents) {
  const ArmConfig c;
  // An object seen by the camera: centre of the view, grip line at -50 deg in the image.
  TablePoint t = vision_to_base(c, Eigen::Vector2d(9.0, 6.0), -50);
  PickObject obj{t.x_mm, t.y_mm, t.yaw_deg, 20.0, 30.0};
  std::vector<Waypoint> w;
  std::string error;
  const Steps start = scan_steps(c);
  ASSERT_TRUE(plan_pick(c, start, obj, "tray", w, error)) << error;
  ASSERT_EQ(phases(w), std::vector<std::string>(std::begin(kNames), std::end(kNames)));
  // Straight lines are split into several moves; the joint moves and gripper entries are one each.
  for (const char* n : {"yaw", "open", "close", "carry", "release", "home"}) EXPECT_EQ(count(w, n), 1u) << n;
  for (const char* n : {"approach", "descend", "lift", "retreat"}) EXPECT_GE(count(w, n), 1u) << n;
  EXPECT_GT(count(w, "approach"), 4u) << "the long slanted approach from the scan pose";
  for (size_t i = 0; i < w.size(); ++i) {
    bool gripper = w[i].name == "open" || w[i].name == "close" || w[i].name == "release";
    EXPECT_EQ(w[i].kind, gripper ? WaypointKind::Gripper : WaypointKind::Move) << w[i].name;
    EXPECT_EQ(w[i].joints, steps_to_joints(c, w[i].steps)) << w[i].name;
    if (gripper) {
      EXPECT_EQ(w[i].steps, w[i - 1].steps) << w[i].name << ": the arm stands still";
      EXPECT_EQ(w[i].dwell_ms, 500);
      EXPECT_EQ(w[i].duration_ms, 0);
    } else {
      // Joint moves last at least min_move_ms; a line's segments are timed by time_line (line_timing_test.cpp).
      const Steps& from = i ? w[i - 1].steps : start;
      int64_t seg = segment_ms(c, steps_to_joints(c, from), w[i].joints);
      bool line = w[i].name == "approach" || w[i].name == "descend" || w[i].name == "lift" || w[i].name == "retreat";
      if (line)
        EXPECT_GE(w[i].duration_ms, 1) << w[i].name << " " << i;
      else
        EXPECT_EQ(w[i].duration_ms, std::max<int64_t>(seg, 200)) << w[i].name << " " << i;
      EXPECT_EQ(w[i].pulse_us, 0) << w[i].name;
      std::string limit;
      EXPECT_TRUE(check_limits(c, w[i].joints, limit)) << w[i].name << ": " << limit;
    }
  }
  EXPECT_STREQ(kind_name(last(w, "open").kind), "gripper");
  EXPECT_STREQ(kind_name(w[0].kind), "move");
  // Opening 20 + margin 5 = 25 mm -> 1500 us; closing squeezes to the closed pulse; release opens the same.
  EXPECT_EQ(last(w, "open").pulse_us, 1500);
  EXPECT_EQ(last(w, "close").pulse_us, 1000);
  EXPECT_EQ(last(w, "release").pulse_us, 1500);
  EXPECT_EQ(w.back().steps, home_steps(c));

  // Heights of the tool point at each phase's end; grasp: 30 mm object, 15 mm finger pads -> fingertips 15 mm
  // above the table.
  auto pose = [&](const char* name) { return tool_pose(c.links, last(w, name).joints); };
  const double tol = 0.3;  // whole steps
  EXPECT_NEAR(pose("approach").x_mm, t.x_mm, tol);
  EXPECT_NEAR(pose("approach").y_mm, t.y_mm, tol);
  EXPECT_NEAR(pose("approach").z_mm, 30 + 40, tol);
  // The approach keeps the tool's yaw of the scan pose; the yaw turns only the wrist roll.
  EXPECT_LT(axis_diff(pose("approach").yaw_deg, tool_pose(c.links, c.scan).yaw_deg), 0.5);
  for (int j = 0; j < 5; ++j) EXPECT_EQ(last(w, "yaw").steps[j], last(w, "approach").steps[j]) << j;
  EXPECT_NEAR(pose("descend").z_mm, 15, tol);
  EXPECT_NEAR(pose("descend").x_mm, t.x_mm, tol);
  EXPECT_NEAR(pose("lift").z_mm, 15 + 30 + 60, tol);
  // The gripper's yaw at the grasp is the grip angle (mod 180) mapped to the base frame.
  for (const char* n : {"yaw", "descend", "lift"}) {
    EXPECT_LT(axis_diff(pose(n).yaw_deg, t.yaw_deg), 0.06) << n;
    EXPECT_LT(pose(n).tilt_deg, 0.05) << n;
  }
  // Carry: over the tray (150, 250, 5), object bottom 60 mm above it; release yaw = the tray's yaw.
  const Place& tray = c.places.at("tray");
  EXPECT_NEAR(pose("carry").x_mm, tray.x_mm, tol);
  EXPECT_NEAR(pose("carry").y_mm, tray.y_mm, tol);
  EXPECT_NEAR(pose("carry").z_mm, 5 + 15 + 60, tol);
  EXPECT_LT(axis_diff(pose("carry").yaw_deg, tray.yaw_deg), 0.06);
  EXPECT_NEAR(pose("retreat").z_mm, 5 + 15 + 60 + 40, tol);
  EXPECT_NEAR(pose("retreat").x_mm, tray.x_mm, tol);
}

// The descend, lift and retreat, read through FK alone: every step target, and the joint-linear path between
// consecutive targets (what the firmware executes), stays within 0.2 mm of the vertical line through the object
// (the place) and within 0.5 deg of its yaw, pointing down.
TEST(Pick, VerticalPhasesAreStraightLinesWithinTheBound) {
  const ArmConfig c;
  for (auto [u, v, grip, height] : {std::tuple{9.0, 6.0, -50.0, 30.0}, {1.0, 1.0, 80.0, 0.0}, {19.0, 14.0, 10.0, 60.0},
                                    {3.0, 13.0, -89.0, 20.0}}) {
    TablePoint t = vision_to_base(c, Eigen::Vector2d(u, v), grip);
    std::vector<Waypoint> w;
    std::string error;
    ASSERT_TRUE(plan_pick(c, scan_steps(c), PickObject{t.x_mm, t.y_mm, t.yaw_deg, 20.0, height}, "tray", w, error))
        << error;
    const Place& tray = c.places.at("tray");
    std::map<std::string, std::tuple<double, double, double>> axis{
        {"descend", {t.x_mm, t.y_mm, t.yaw_deg}}, {"lift", {t.x_mm, t.y_mm, t.yaw_deg}},
        {"retreat", {tray.x_mm, tray.y_mm, tray.yaw_deg}}};
    for (const auto& [name, line] : axis) {
      auto [x, y, yaw] = line;
      double worst_mm = 0, worst_yaw = 0, worst_tilt = 0;
      size_t segments = 0;
      for (size_t i = 1; i < w.size(); ++i) {
        if (w[i].name != name) continue;
        ++segments;
        const Joints a = steps_to_joints(c, w[i - 1].steps), b = w[i].joints;
        for (int k = 0; k <= 50; ++k) {  // k = 50: the step target itself
          Joints q{};
          for (int j = 0; j < kJoints; ++j) q[j] = a[j] + (b[j] - a[j]) * k / 50.0;
          ToolPose p = tool_pose(c.links, q);
          worst_mm = std::max(worst_mm, std::hypot(p.x_mm - x, p.y_mm - y));
          worst_yaw = std::max(worst_yaw, axis_diff(p.yaw_deg, yaw));
          worst_tilt = std::max(worst_tilt, p.tilt_deg);
        }
      }
      EXPECT_GE(segments, 1u) << name;
      EXPECT_LE(worst_mm, 0.2) << name << " at (" << u << ", " << v << ") cm";
      EXPECT_LE(worst_yaw, 0.5) << name;
      EXPECT_LE(worst_tilt, 0.5) << name;
    }
  }
}

// The joint-move pick (lines = false): the same phases, one move each, and the same final poses within steps.
TEST(Pick, JointMovePickHasOneMovePerPhase) {
  const ArmConfig c;
  TablePoint t = vision_to_base(c, Eigen::Vector2d(9.0, 6.0), -50);
  std::vector<Waypoint> lines, joints;
  std::string error;
  ASSERT_TRUE(plan_pick(c, scan_steps(c), PickObject{t.x_mm, t.y_mm, t.yaw_deg, 20.0, 30.0}, "tray", lines, error));
  ASSERT_TRUE(plan_pick(c, scan_steps(c), PickObject{t.x_mm, t.y_mm, t.yaw_deg, 20.0, 30.0}, "tray", joints, error,
                        false));
  ASSERT_EQ(joints.size(), std::size(kNames));
  EXPECT_EQ(phases(joints), phases(lines));
  for (const char* n : {"descend", "lift", "carry", "retreat", "home"}) {
    ToolPose a = tool_pose(c.links, last(lines, n).joints), b = tool_pose(c.links, last(joints, n).joints);
    EXPECT_NEAR(a.x_mm, b.x_mm, 0.3) << n;
    EXPECT_NEAR(a.y_mm, b.y_mm, 0.3) << n;
    EXPECT_NEAR(a.z_mm, b.z_mm, 0.3) << n;
  }
}

TEST(Pick, GripperYawIsTheGripAngleModulo180) {
  const ArmConfig c;
  for (double grip : {-89.0, -50.0, 0.0, 13.67, 68.96, 90.0}) {
    TablePoint t = vision_to_base(c, Eigen::Vector2d(10.0, 7.5), grip);
    std::vector<Waypoint> w;
    std::string error;
    ASSERT_TRUE(plan_pick(c, home_steps(c), PickObject{t.x_mm, t.y_mm, t.yaw_deg, 10, 10}, "tray", w, error))
        << error;
    ToolPose p = tool_pose(c.links, last(w, "descend").joints);
    EXPECT_LT(axis_diff(p.yaw_deg, t.yaw_deg), 0.06) << grip;
    // The default mount turns image angles by 90 deg and mirrors them: base yaw = 90 - image angle (mod 180).
    EXPECT_LT(axis_diff(p.yaw_deg, 90 - grip), 0.06) << grip;
  }
}

TEST(Pick, ShallowObjectGraspedAtTheFingerClearance) {
  const ArmConfig c;
  std::vector<Waypoint> w;
  std::string error;
  ASSERT_TRUE(plan_pick(c, home_steps(c), PickObject{280, -30, 10, 8, 5}, "tray", w, error)) << error;
  EXPECT_NEAR(tool_pose(c.links, last(w, "descend").joints).z_mm, 2, 0.3);
}

TEST(Pick, OpeningWiderThanTheGripperIsRefused) {
  const ArmConfig c;
  std::vector<Waypoint> w;
  std::string error;
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, 52, 10}, "tray", w, error));
  EXPECT_EQ(error, "gripper opening 52.0 mm is wider than the gripper's 50.0 mm (arm.gripper.max_opening_mm)");
  EXPECT_TRUE(w.empty());
  // Within the gripper but not with the margin: opens fully.
  ASSERT_TRUE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, 48, 10}, "tray", w, error)) << error;
  EXPECT_EQ(last(w, "open").pulse_us, 2000);
}

TEST(Pick, Errors) {
  const ArmConfig c;
  std::vector<Waypoint> w;
  std::string error;
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, 10, 10}, "bin", w, error));
  EXPECT_EQ(error, "unknown place 'bin' (arm.places has: tray)");
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{700, 0, 0, 10, 10}, "tray", w, error));
  EXPECT_EQ(error.rfind("approach: target (700.0, 0.0, 50.0) mm is out of reach", 0), 0u) << error;
  // Reachable above but not down at the table: the descend fails.
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{415, 0, 0, 10, 10}, "tray", w, error));
  EXPECT_EQ(error.rfind("descend: ", 0), 0u) << error;
  // A place out of reach fails at the carry.
  ArmConfig far = c;
  far.places["tray"] = Place{0, 600, 0, 0};
  EXPECT_FALSE(plan_pick(far, home_steps(c), PickObject{280, 0, 0, 10, 10}, "tray", w, error));
  EXPECT_EQ(error.rfind("carry: ", 0), 0u) << error;
  // Not a number (say, from a detection without table coordinates) never reaches the steps.
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{NAN, 0, 0, 10, 10}, "tray", w, error));
  EXPECT_EQ(error, "approach: target has a coordinate or yaw that is not a finite number");
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, NAN, 10}, "tray", w, error));
  EXPECT_EQ(error, "gripper opening is not a finite number");
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, 10, NAN}, "tray", w, error));
  EXPECT_EQ(error, "object height is not a finite number");
  EXPECT_FALSE(plan_pick(c, home_steps(c), PickObject{280, 0, 0, 10, -3}, "tray", w, error));
  EXPECT_EQ(error, "object height -3.0 mm is negative");
  // Out of joint limits names the joint.
  ArmConfig tight = c;
  tight.joints[0].min_deg = -10;
  tight.joints[0].max_deg = 10;
  EXPECT_FALSE(plan_pick(tight, home_steps(c), PickObject{0, 300, 0, 10, 10}, "tray", w, error));
  EXPECT_NE(error.find("J1 (base yaw)"), std::string::npos) << error;
  EXPECT_EQ(error.rfind("approach: ", 0), 0u) << error;
}

TEST(Pick, EveryPointOfTheDefaultViewIsPickable) {
  // The default mount and scan pose cover a 20 x 15 cm view (800 x 600 px at 40 px/cm): all of it, at any grip
  // angle, for objects up to 60 mm tall, goes to the tray from the scan pose.
  const ArmConfig c;
  int planned = 0;
  for (double u = 0; u <= 20; u += 2.5) {
    for (double v = 0; v <= 15; v += 2.5) {
      for (double grip : {-90.0, -45.0, 0.0, 30.0, 89.0}) {
        for (double height : {0.0, 20.0, 60.0}) {
          TablePoint t = vision_to_base(c, Eigen::Vector2d(u, v), grip);
          std::vector<Waypoint> w;
          std::string error;
          ASSERT_TRUE(plan_pick(c, scan_steps(c), PickObject{t.x_mm, t.y_mm, t.yaw_deg, 30, height}, "tray", w, error))
              << "(" << u << ", " << v << ") cm, grip " << grip << ", height " << height << ": " << error;
          ++planned;
        }
      }
    }
  }
  EXPECT_EQ(planned, 9 * 7 * 5 * 3);
}
