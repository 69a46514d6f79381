// homing.cpp - homing cycle state machine (main loop), moving joints through stepper jogs.
#include "homing.h"

#include "config.h"
#include "hal.h"
#include "rbx1_proto.h"
#include "settings.h"
#include "stepper.h"
#include "system.h"

#define PH_IDLE 0
#define PH_CLEAR 1    // switch already pressed at the start: move off it first
#define PH_SEEK 2     // towards the switch until it triggers
#define PH_RELEASE 3  // away from it until it releases: that point is HOME_POSITION

static uint8_t pending;  // joints still to home
static uint8_t joint;    // the joint being homed
static uint8_t phase;

void homing_init(void) {
  pending = 0;
  phase = PH_IDLE;
}

uint8_t homing_active(void) { return phase != PH_IDLE; }

void homing_cancel(void) {
  pending = 0;
  phase = PH_IDLE;
}

static uint32_t seek_steps(uint8_t j) {
  int64_t span = (int64_t)SETTING(j, RBX1_KEY_SOFT_MAX) - (int64_t)SETTING(j, RBX1_KEY_SOFT_MIN);
  span += span / 10 + 1000;  // the whole travel plus a margin: from anywhere, the switch must be reached
  return span > 0x7FFFFFFFLL ? 0x7FFFFFFFUL : (uint32_t)span;
}

static uint32_t backoff_speed(uint8_t j) {
  uint32_t v = (uint32_t)SETTING(j, RBX1_KEY_HOME_SPEED) / HOMING_BACKOFF_DIVISOR;
  return v ? v : 1;
}

static void fail(void) {
  sys_set_fault(RBX1_FAULT_HOMING_FAILED);
  homing_cancel();
}

// Starts the next joint, or ends the cycle.
static void next_joint(void) {
  while (pending) {
    uint8_t j = 0;
    while (!(pending & (1u << j))) j++;
    pending = (uint8_t)(pending & ~(1u << j));
    joint = j;
    sys.homed = (uint8_t)(sys.homed & ~(1u << j));
    uint8_t towards_max = SETTING(j, RBX1_KEY_HOME_DIR) != 0;
    if (hal_limit_inputs() & (1u << j)) {
      phase = PH_CLEAR;
      st_jog(j, (uint8_t)!towards_max, HOMING_BACKOFF_MAX_STEPS, backoff_speed(j), 0);
    } else {
      phase = PH_SEEK;
      st_jog(j, towards_max, seek_steps(j), (uint32_t)SETTING(j, RBX1_KEY_HOME_SPEED), 1);
    }
    return;
  }
  phase = PH_IDLE;
}

void homing_start(uint8_t mask) {
  pending = (uint8_t)(mask & RBX1_ALL_JOINTS_MASK);
  next_joint();
}

void homing_poll(void) {
  if (phase == PH_IDLE) return;
  if (sys_faulted() || st_stopping()) {
    homing_cancel();
    return;
  }
  if (st_busy()) return;
  uint8_t j = joint, towards_max = SETTING(j, RBX1_KEY_HOME_DIR) != 0;
  if (!st_jog_hit()) {
    fail();
    return;
  }
  switch (phase) {
    case PH_CLEAR:
      phase = PH_SEEK;
      st_jog(j, towards_max, seek_steps(j), (uint32_t)SETTING(j, RBX1_KEY_HOME_SPEED), 1);
      break;
    case PH_SEEK:
      phase = PH_RELEASE;
      st_jog(j, (uint8_t)!towards_max, HOMING_BACKOFF_MAX_STEPS, backoff_speed(j), 0);
      break;
    default:  // PH_RELEASE: the switch just released
      st_set_joint_position(j, SETTING(j, RBX1_KEY_HOME_POSITION));
      sys.homed = (uint8_t)(sys.homed | (1u << j));
      next_joint();
      break;
  }
}
