// urdf_kdl_test.cpp - the URDF checked by others' code: KDL's FK from it against fk(), limits read back by urdfdom.
#include <numbers>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>
#include <urdf_parser/urdf_parser.h>

#include "kinematics.hpp"
#include "urdf.hpp"
#include "vision_map.hpp"

namespace rbx1::arm {
namespace {


KDL::Chain chain_to(const ArmConfig& cfg, const std::string& tip) {
  KDL::Tree tree;
  EXPECT_TRUE(kdl_parser::treeFromString(urdf(cfg), tree));
  KDL::Chain chain;
  EXPECT_TRUE(tree.getChain("base_link", tip, chain));
  return chain;
}

Eigen::Isometry3d kdl_fk(const KDL::Chain& chain, const KDL::JntArray& q) {
  KDL::ChainFkSolverPos_recursive solver(chain);
  KDL::Frame f;
  EXPECT_GE(solver.JntToCart(q, f), 0);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    t.translation()[r] = f.p[r] * 1000.0;  // metres -> mm
    for (int c = 0; c < 3; ++c) t.linear()(r, c) = f.M(r, c);
  }
  return t;
}

struct Agreement {
  double max_mm = 0, max_deg = 0;
};

// KDL's tool0 against fk() on n random joint sets uniform within the config's limits (fixed seed).
Agreement compare(const ArmConfig& cfg, int n) {
  KDL::Chain chain = chain_to(cfg, "tool0");
  EXPECT_EQ(chain.getNrOfJoints(), unsigned(kJoints));
  for (unsigned i = 0, j = 0; i < chain.getNrOfSegments(); ++i) {
    if (chain.getSegment(i).getJoint().getType() != KDL::Joint::None) {
      EXPECT_EQ(chain.getSegment(i).getJoint().getName(), kUrdfJointNames[j++]);
    }
  }
  std::mt19937_64 rng(25);
  Agreement a;
  KDL::JntArray q(kJoints);
  for (int k = 0; k < n; ++k) {
    Joints deg;
    for (int j = 0; j < kJoints; ++j) {
      deg[j] = std::uniform_real_distribution<double>(cfg.joints[j].min_deg, cfg.joints[j].max_deg)(rng);
      q(j) = deg[j] * std::numbers::pi / 180;
    }
    Eigen::Isometry3d ours = fk(cfg.links, deg), theirs = kdl_fk(chain, q);
    a.max_mm = std::max(a.max_mm, (ours.translation() - theirs.translation()).norm());
    Eigen::Quaterniond d(ours.linear().transpose() * theirs.linear());  // atan2: exact near zero, unlike acos
    double angle = 2 * std::atan2(d.vec().norm(), std::fabs(d.w())) * 180 / std::numbers::pi;
    a.max_deg = std::max(a.max_deg, angle);
  }
  return a;
}

TEST(UrdfKdl, ToolFrameMatchesFkOnTenThousandJointSets) {
  Agreement a = compare(default_arm_config(), 10000);
  std::printf("default links: max position error %.3g mm, max orientation error %.3g deg\n", a.max_mm, a.max_deg);
  EXPECT_LT(a.max_mm, 0.01);
  EXPECT_LT(a.max_deg, 0.01);
}

TEST(UrdfKdl, OtherLinkLengthsAndLimits) {
  ArmConfig cfg = default_arm_config();
  cfg.links = Links{310.5, 180.0, 262.25, 95.0};
  cfg.joints[1].min_deg = -80;
  cfg.joints[2].max_deg = 135;
  Agreement a = compare(cfg, 10000);
  std::printf("other links: max position error %.3g mm, max orientation error %.3g deg\n", a.max_mm, a.max_deg);
  EXPECT_LT(a.max_mm, 0.01);
  EXPECT_LT(a.max_deg, 0.01);
}

TEST(UrdfKdl, JointLimitsAreTheConfigs) {
  ArmConfig cfg = default_arm_config();
  cfg.joints[4].min_deg = -97.5;
  cfg.gripper.max_opening_mm = 64;
  urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf(cfg));
  ASSERT_TRUE(model);
  for (int j = 0; j < kJoints; ++j) {
    auto joint = model->getJoint(kUrdfJointNames[j]);
    ASSERT_TRUE(joint && joint->limits) << kUrdfJointNames[j];
    EXPECT_EQ(joint->type, urdf::Joint::REVOLUTE);
    EXPECT_NEAR(joint->limits->lower, cfg.joints[j].min_deg * std::numbers::pi / 180, 1e-12) << kUrdfJointNames[j];
    EXPECT_NEAR(joint->limits->upper, cfg.joints[j].max_deg * std::numbers::pi / 180, 1e-12) << kUrdfJointNames[j];
  }
  auto finger = model->getJoint(kUrdfFingerJoint);
  ASSERT_TRUE(finger && finger->limits);
  EXPECT_EQ(finger->type, urdf::Joint::PRISMATIC);
  EXPECT_NEAR(finger->limits->lower, 0, 1e-12);
  EXPECT_NEAR(finger->limits->upper, 0.032, 1e-12);  // half the opening, metres
  auto mimic = model->getJoint("finger_right_joint");
  ASSERT_TRUE(mimic && mimic->mimic);
  EXPECT_EQ(mimic->mimic->joint_name, kUrdfFingerJoint);
}

// At the scan pose the camera frame's image axes land where vision_to_base puts them, and it looks down.
TEST(UrdfKdl, CameraOpticalFollowsTheMount) {
  for (bool flip : {true, false}) {
    ArmConfig cfg = default_arm_config();
    cfg.camera.rotation_deg = 30;
    cfg.camera.flip_y = flip;
    KDL::JntArray q(kJoints);
    for (int j = 0; j < kJoints; ++j) q(j) = cfg.scan[j] * std::numbers::pi / 180;
    Eigen::Isometry3d cam = kdl_fk(chain_to(cfg, "camera_optical"), q);
    TablePoint o = vision_to_base(cfg, {0, 0}, 0), x = vision_to_base(cfg, {1, 0}, 0), y = vision_to_base(cfg, {0, 1}, 0);
    Eigen::Vector3d ex(x.x_mm - o.x_mm, x.y_mm - o.y_mm, 0), ey(y.x_mm - o.x_mm, y.y_mm - o.y_mm, 0);
    EXPECT_LT((cam.linear().col(0) - ex.normalized()).norm(), 1e-9);
    EXPECT_LT((cam.linear().col(1) - ey.normalized()).norm(), 1e-9);
    if (flip) {
      EXPECT_LT((cam.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-9);  // looking down
    }
    EXPECT_LT((cam.translation() - fk(cfg.links, cfg.scan).translation()).norm(), 1e-6);
  }
}

// The left finger slides along tool0's x by the joint value (metres).
TEST(UrdfKdl, FingerSlidesAlongTheClosingLine) {
  ArmConfig cfg = default_arm_config();
  KDL::Chain chain = chain_to(cfg, "finger_left");
  ASSERT_EQ(chain.getNrOfJoints(), unsigned(kJoints + 1));
  Joints deg{10, 20, 30, 40, 50, 60};
  KDL::JntArray q(kJoints + 1);
  for (int j = 0; j < kJoints; ++j) q(j) = deg[j] * std::numbers::pi / 180;
  q(kJoints) = 0.02;
  Eigen::Isometry3d tool = fk(cfg.links, deg), finger = kdl_fk(chain, q);
  EXPECT_LT((finger.translation() - (tool.translation() + 20.0 * tool.linear().col(0))).norm(), 1e-6);
  EXPECT_NEAR(finger_position_m(cfg.gripper, cfg.gripper.open_us), 0.025, 1e-12);
  EXPECT_NEAR(finger_position_m(cfg.gripper, cfg.gripper.closed_us), 0.0, 1e-12);
}

}  // namespace
}  // namespace rbx1::arm
