// system.cpp - firmware state: fault latch and the derived state machine.
#include "system.h"

#include "hal.h"
#include "homing.h"
#include "queue.h"
#include "rbx1_proto.h"
#include "stepper.h"

system_t sys;

void sys_init(void) {
  sys.faults = 0;
  sys.homed = 0;
  sys.enabled = 0;
  sys.stop_fault = 0;
}

void sys_set_fault(uint16_t bits) {
  hal_irq_state s = hal_irq_save();
  sys.faults = (uint16_t)(sys.faults | bits);
  hal_irq_restore(s);
}

uint16_t sys_faults(void) {
  hal_irq_state s = hal_irq_save();
  uint16_t f = sys.faults;
  hal_irq_restore(s);
  return f;
}

void sys_clear_faults(void) {
  hal_irq_state s = hal_irq_save();
  sys.faults = 0;
  hal_irq_restore(s);
}

uint8_t sys_faulted(void) { return (sys_faults() & RBX1_FAULTS_LATCHING) != 0; }

uint8_t sys_all_homed(void) { return sys.homed == RBX1_ALL_JOINTS_MASK; }

uint8_t sys_state(void) {
  if (sys_faulted()) return RBX1_STATE_FAULT;
  if (st_stopping() || sys.stop_fault) return RBX1_STATE_STOPPING;  // until at rest and its fault latched
  if (homing_active()) return RBX1_STATE_HOMING;
  if (st_busy() || queue_count() > 0) return RBX1_STATE_MOVING;
  return RBX1_STATE_IDLE;
}
