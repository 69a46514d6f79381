// test_settings.cpp - configuration: ranges, EEPROM persistence across power cycles, blank/corrupt EEPROM defaults.
#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

TEST_F(Fw, BlankEepromGivesDefaultsAndTheInfoFault) {
  rbx1_status_resp s = status();
  EXPECT_TRUE(s.faults & RBX1_FAULT_EEPROM_DEFAULTS);
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  int32_t v = 0;
  EXPECT_EQ(config_get(0, RBX1_KEY_MAX_SPEED, &v), RBX1_OK);
  EXPECT_EQ(v, 4000);
  EXPECT_EQ(config_get(5, RBX1_KEY_SOFT_MIN, &v), RBX1_OK);
  EXPECT_EQ(v, -100000);
  EXPECT_EQ(config_get(RBX1_GLOBAL_JOINT, RBX1_KEY_HEARTBEAT_MS, &v), RBX1_OK);
  EXPECT_EQ(v, 1000);
}

TEST_F(Fw, ConfigPersistsAcrossResetAndCorruptionFallsBack) {
  ASSERT_EQ(config_set(3, RBX1_KEY_ACCEL, 12345), RBX1_OK);
  ASSERT_EQ(config_set(RBX1_GLOBAL_JOINT, RBX1_KEY_GRIPPER_MIN_US, 900), RBX1_OK);
  boot();
  int32_t v = 0;
  EXPECT_EQ(config_get(3, RBX1_KEY_ACCEL, &v), RBX1_OK);
  EXPECT_EQ(v, 12345);
  EXPECT_EQ(config_get(RBX1_GLOBAL_JOINT, RBX1_KEY_GRIPPER_MIN_US, &v), RBX1_OK);
  EXPECT_EQ(v, 900);
  EXPECT_FALSE(status().faults & RBX1_FAULT_EEPROM_DEFAULTS);
  sim::board().eeprom[20] ^= 0x01;  // one flipped bit
  boot();
  EXPECT_TRUE(status().faults & RBX1_FAULT_EEPROM_DEFAULTS);
  EXPECT_EQ(config_get(3, RBX1_KEY_ACCEL, &v), RBX1_OK);
  EXPECT_EQ(v, 8000);
  // CONFIG_RESET writes the defaults: valid again after the next power cycle.
  EXPECT_EQ(simple(RBX1_MSG_CONFIG_RESET), RBX1_OK);
  boot();
  EXPECT_FALSE(status().faults & RBX1_FAULT_EEPROM_DEFAULTS);
}

TEST_F(Fw, ConfigSetValidatesRangesKeysAndJoints) {
  EXPECT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, 0), RBX1_BAD_ARG);
  EXPECT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, 20001), RBX1_BAD_ARG);
  EXPECT_EQ(config_set(0, RBX1_KEY_MAX_SPEED, 20000), RBX1_OK);
  EXPECT_EQ(config_set(6, RBX1_KEY_MAX_SPEED, 100), RBX1_BAD_ARG);
  EXPECT_EQ(config_set(0, 9, 1), RBX1_BAD_ARG);
  EXPECT_EQ(config_set(0, RBX1_KEY_HEARTBEAT_MS, 500), RBX1_BAD_ARG);  // a global key needs joint 0xFF
  EXPECT_EQ(config_set(RBX1_GLOBAL_JOINT, RBX1_KEY_HEARTBEAT_MS, 99), RBX1_BAD_ARG);
  EXPECT_EQ(config_set(1, RBX1_KEY_SOFT_MIN, 100001), RBX1_BAD_ARG);  // above SOFT_MAX
  EXPECT_EQ(config_set(RBX1_GLOBAL_JOINT, RBX1_KEY_GRIPPER_MAX_US, 999), RBX1_BAD_ARG);  // below MIN
  int32_t v = 0;
  EXPECT_EQ(config_get(0, 99, &v), RBX1_BAD_ARG);
  EXPECT_EQ(config_get(0, RBX1_KEY_MAX_SPEED, &v), RBX1_OK);
  EXPECT_EQ(v, 20000);
}

TEST_F(Fw, EepromWriteFailureIsReported) {
  sim::board().eeprom_broken = true;
  EXPECT_EQ(config_set(0, RBX1_KEY_ACCEL, 100), RBX1_EEPROM_ERROR);
}

}  // namespace
}  // namespace rbx1::fwtest
