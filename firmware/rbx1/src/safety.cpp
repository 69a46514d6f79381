// safety.cpp - e-stop and stop requests, fault clearing, heartbeat supervision.
#include "safety.h"

#include "hal.h"
#include "homing.h"
#include "queue.h"
#include "rbx1_proto.h"
#include "settings.h"
#include "stepper.h"
#include "system.h"

static uint32_t last_request_ms;

void safety_init(void) { last_request_ms = hal_millis(); }

void safety_request_seen(void) { last_request_ms = hal_millis(); }

void safety_estop(void) {
  st_abort();
  sys_set_fault(RBX1_FAULT_ESTOP_COMMAND);
  sys.stop_fault = 0;
  homing_cancel();
}

void safety_stop(uint16_t fault_at_rest) {
  homing_cancel();
  if (!st_busy() && queue_count() == 0) {  // already at rest
    if (fault_at_rest) sys_set_fault(fault_at_rest);
    return;
  }
  sys.stop_fault = (uint16_t)(sys.stop_fault | fault_at_rest);
  st_stop();
}

uint8_t safety_clear_fault(void) {
  if (hal_estop_input()) return RBX1_ESTOP_ACTIVE;
  sys_clear_faults();
  sys.stop_fault = 0;
  return RBX1_OK;
}

void safety_poll(void) {
  uint8_t state = sys_state();
  if (sys.stop_fault && !st_stopping() && !st_busy()) {
    sys_set_fault(sys.stop_fault);
    sys.stop_fault = 0;
  }
  if (state == RBX1_STATE_MOVING || state == RBX1_STATE_HOMING) {
    uint32_t limit = (uint32_t)SETTING_GLOBAL(RBX1_KEY_HEARTBEAT_MS);
    if ((uint32_t)(hal_millis() - last_request_ms) > limit) safety_stop(RBX1_FAULT_HEARTBEAT_LOST);
  }
}
