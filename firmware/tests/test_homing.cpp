// test_homing.cpp - homing against simulated switches: position declared at the switch, failures latch.
#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

TEST_F(Fw, HomingFindsEverySwitchAndDeclaresHomePosition) {
  ASSERT_EQ(enable(1), RBX1_OK);
  // Switches 300..800 steps below the start (HOME_DIR 0), one joint homing towards max.
  for (int j = 0; j < RBX1_JOINTS; j++) sim::board().switches[j] = {true, -300 - 100 * j, true};
  sim::board().switches[4] = {true, 450, false};
  ASSERT_EQ(config_set(4, RBX1_KEY_HOME_DIR, 1), RBX1_OK);
  ASSERT_EQ(config_set(0, RBX1_KEY_HOME_POSITION, -1000), RBX1_OK);
  ASSERT_EQ(config_set(1, RBX1_KEY_HOME_SPEED, 2000), RBX1_OK);
  EXPECT_EQ(home(0), RBX1_OK);
  EXPECT_EQ(status().state, RBX1_STATE_HOMING);
  EXPECT_EQ(move({0, 0, 0, 0, 0, 0}), RBX1_BUSY);
  run_until_idle(20000);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.homed, RBX1_ALL_JOINTS_MASK);
  EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, 0);
  EXPECT_EQ(s.position[0], -1000);
  for (int j = 1; j < RBX1_JOINTS; j++) EXPECT_EQ(s.position[j], 0) << "joint " << j + 1;
  // Each joint rests on the first released step next to its switch.
  for (int j = 0; j < RBX1_JOINTS; j++) {
    int64_t expect = j == 4 ? 449 : -300 - 100 * j + 1;
    EXPECT_EQ(sim::board().net[j], expect) << "joint " << j + 1;
  }
  EXPECT_EQ(move({-900, 10, 0, 0, 0, 0}), RBX1_OK);  // homed: moves are allowed
}

TEST_F(Fw, HomingStartingOnTheSwitchBacksOffFirst) {
  ASSERT_EQ(enable(1), RBX1_OK);
  sim::board().switches[2] = {true, 10, true};  // already pressed at 0
  EXPECT_EQ(home(1u << 2), RBX1_OK);
  run_until_idle(20000);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.homed, 1u << 2);
  EXPECT_EQ(sim::board().net[2], 11);
  EXPECT_EQ(s.faults & RBX1_FAULTS_LATCHING, 0);
}

TEST_F(Fw, HomingPartOfTheJointsKeepsTheOthers) {
  ASSERT_EQ(enable(1), RBX1_OK);
  ASSERT_EQ(set_position({100, 200, 300, 400, 500, 600}), RBX1_OK);  // all six declared
  sim::board().switches[1] = {true, 200 - 150, true};                 // joint 2's switch 150 steps below
  ASSERT_EQ(config_set(1, RBX1_KEY_HOME_POSITION, -7), RBX1_OK);
  EXPECT_EQ(home(1u << 1), RBX1_OK);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.homed, RBX1_ALL_JOINTS_MASK & ~(1u << 1)) << "the joint being homed is not homed until it is";
  EXPECT_EQ(move({100, 200, 300, 400, 500, 600}), RBX1_BUSY);
  run_until_idle(20000);
  s = status();
  EXPECT_EQ(s.homed, RBX1_ALL_JOINTS_MASK);
  EXPECT_EQ(s.position[1], -7);
  for (int j : {0, 2, 3, 4, 5}) EXPECT_EQ(s.position[j], 100 * (j + 1)) << "joint " << j + 1 << " kept its position";
  EXPECT_EQ(move({100, -7, 300, 400, 500, 600}), RBX1_OK);
}

TEST_F(Fw, HomingWithoutSwitchFails) {
  ASSERT_EQ(enable(1), RBX1_OK);
  ASSERT_EQ(config_set(1, RBX1_KEY_SOFT_MIN, -1000), RBX1_OK);
  ASSERT_EQ(config_set(1, RBX1_KEY_SOFT_MAX, 1000), RBX1_OK);
  EXPECT_EQ(home(1u << 1), RBX1_OK);
  run_until_idle(20000);
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(s.faults & RBX1_FAULT_HOMING_FAILED);
  EXPECT_EQ(s.homed, 0);
  EXPECT_EQ(sim::board().net[1], -(2000 + 200 + 1000));  // the whole travel plus margin, then gave up
  EXPECT_EQ(home(0x40), RBX1_FAULT_ACTIVE);
  EXPECT_EQ(simple(RBX1_MSG_CLEAR_FAULT), RBX1_OK);
  EXPECT_EQ(home(0x40), RBX1_BAD_ARG);
}

}  // namespace
}  // namespace rbx1::fwtest
