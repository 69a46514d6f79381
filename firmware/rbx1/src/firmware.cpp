// firmware.cpp - power-up sequence and main loop: link, safety supervision, homing. Motion runs in interrupts.
#include "firmware.h"

#include "hal.h"
#include "homing.h"
#include "planner.h"
#include "protocol.h"
#include "queue.h"
#include "rbx1_proto.h"
#include "safety.h"
#include "settings.h"
#include "stepper.h"
#include "system.h"

void fw_setup(void) {
  // RAM state first: the interrupts hal_init() starts read it.
  sys_init();
  queue_init();
  st_init();
  homing_init();
  uint16_t info = 0;
  if (!settings_load()) info |= RBX1_FAULT_EEPROM_DEFAULTS;
  hal_init();
  if (hal_reset_by_watchdog()) info |= RBX1_FAULT_WATCHDOG_RESET;
  sys_set_fault(info);
  protocol_init();
  safety_init();
}

void fw_loop(void) {
  hal_watchdog_kick();
  protocol_poll();
  planner_poll();  // after the answers: a MOVE's answer never waits for the look-ahead
  safety_poll();
  homing_poll();
}
