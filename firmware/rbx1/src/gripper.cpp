// gripper.cpp - gripper servo pulse checks.
#include "gripper.h"

#include "rbx1_proto.h"
#include "settings.h"

uint8_t gripper_check(uint16_t pulse_us) {
  if ((int32_t)pulse_us < SETTING_GLOBAL(RBX1_KEY_GRIPPER_MIN_US) ||
      (int32_t)pulse_us > SETTING_GLOBAL(RBX1_KEY_GRIPPER_MAX_US))
    return RBX1_BAD_ARG;
  return RBX1_OK;
}
