// stepper.h - stepper driver: executes queue entries with step pulses from the step timer interrupt and
// runs the 1 kHz profile tick (velocity ramp, limit/e-stop polling, dwells, entry sequencing).
#ifndef RBX1_STEPPER_H
#define RBX1_STEPPER_H

#include <stdint.h>

#include "rbx1_messages.h"

void st_init(void);
// Step timer interrupt: one dominant-joint step with Bresenham steps of the others (see the budget in stepper.cpp).
void st_step_isr(void);
// 1 kHz profile tick: lower priority than the step interrupt (interruptible by it on the AVR).
void st_profile_isr(void);

// E-stop / fault: pulses stop at once, the executing entry and the queue are dropped. Interrupt-safe.
void st_abort(void);
// Controlled stop: the executing move decelerates to rest, waiting entries are dropped.
void st_stop(void);
// 1 until a controlled stop has reached rest.
uint8_t st_stopping(void);
// 1 while an entry (move, gripper dwell, homing jog) executes.
uint8_t st_busy(void);
// Positions in steps (interrupt-safe copy) and their declaration (SET_POSITION, homing).
void st_position(int32_t out[RBX1_JOINTS]);
void st_set_position(const int32_t p[RBX1_JOINTS]);
void st_set_joint_position(uint8_t joint, int32_t p);
// Completed MOVE and GRIPPER entries since power-up.
uint16_t st_moves_done(void);
// Last gripper pulse commanded (0 = none yet).
uint16_t st_gripper_us(void);

// Homing jog: one joint at constant `speed` steps/s for at most max_steps, stopping early when its limit input
// reads `stop_level` (1 = triggered). st_jog_hit() tells whether it stopped on the switch.
void st_jog(uint8_t joint, uint8_t positive, uint32_t max_steps, uint32_t speed, uint8_t stop_level);
uint8_t st_jog_hit(void);

#endif
