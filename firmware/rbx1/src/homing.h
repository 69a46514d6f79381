// homing.h - homing cycle: per joint, seek the limit switch at HOME_SPEED, back off until it releases, and
// declare HOME_POSITION there. Joints home one after another (J1 first); a missing switch is HOMING_FAILED.
#ifndef RBX1_HOMING_H
#define RBX1_HOMING_H

#include <stdint.h>

void homing_init(void);
// Starts homing the joints in mask (bit per joint, non-zero). The caller checked state and enable.
void homing_start(uint8_t mask);
// Abandons the cycle (STOP, faults); the joint being homed stays unhomed.
void homing_cancel(void);
uint8_t homing_active(void);
// Advances the cycle from the main loop.
void homing_poll(void);

#endif
