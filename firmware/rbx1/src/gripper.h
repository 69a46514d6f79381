// gripper.h - gripper servo: pulse width validation against the configured GRIPPER_MIN_US..GRIPPER_MAX_US.
// The pulse itself is set when the queue reaches the entry (stepper.cpp) through hal_servo_write().
#ifndef RBX1_GRIPPER_H
#define RBX1_GRIPPER_H

#include <stdint.h>

// RBX1_OK, or RBX1_BAD_ARG when pulse_us is outside the configured range.
uint8_t gripper_check(uint16_t pulse_us);

#endif
