// system.h - firmware state: faults, homed and enabled flags, and the state derived from them (PROTOCOL.md States).
#ifndef RBX1_SYSTEM_H
#define RBX1_SYSTEM_H

#include <stdint.h>

struct system_t {
  uint16_t faults;      // RBX1_FAULT_* bits; ISRs set bits too, so main-loop code uses the accessors below
  uint8_t homed;        // bit per joint
  uint8_t enabled;      // stepper drivers on
  uint16_t stop_fault;  // fault to latch when the controlled stop reaches rest (HEARTBEAT_LOST) or 0
};
extern system_t sys;

// Power-up state: IDLE, drivers off, nothing homed, no fault.
void sys_init(void);
// Latches fault bits (interrupt-safe).
void sys_set_fault(uint16_t bits);
// Current fault bits (interrupt-safe read).
uint16_t sys_faults(void);
// Clears all fault bits (interrupt-safe).
void sys_clear_faults(void);
// 1 when a latching fault holds the machine in FAULT.
uint8_t sys_faulted(void);
// RBX1_STATE_* derived from faults, stop, homing, queue and stepper.
uint8_t sys_state(void);
// 1 when every joint is homed or declared.
uint8_t sys_all_homed(void);

#endif
