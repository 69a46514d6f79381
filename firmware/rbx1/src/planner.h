// planner.h - turns a MOVE into a coordinated block: per-joint step counts for the Bresenham/DDA and a
// trapezoidal velocity profile of the dominant joint within every joint's MAX_SPEED and ACCEL.
#ifndef RBX1_PLANNER_H
#define RBX1_PLANNER_H

#include <stdint.h>

#define BLOCK_MOVE 0
#define BLOCK_GRIPPER 1

// Velocities are 16.16 fixed point steps/s: 1 step/s = 65536 (enough for 20000 steps/s in 32 bits).
#define PLAN_V_ONE 65536UL

struct plan_block {
  uint8_t kind;           // BLOCK_MOVE or BLOCK_GRIPPER
  uint8_t dir_positive;   // bit per joint: moving towards larger step counts
  uint16_t duration_ms;   // minimum time of the entry: the MOVE's duration_ms or the gripper's dwell
  uint16_t planned_ms;    // the profile's own time (for the move log)
  uint16_t pulse_us;      // gripper pulse
  uint32_t steps[6];      // |target - start| per joint
  uint32_t n;             // dominant joint's steps (the DDA's tick count)
  uint32_t ramp_steps;    // dominant steps of the ramp-up (and of the ramp-down)
  uint32_t v0;            // start/end velocity (the first step's rate)
  uint32_t vc;            // cruise velocity
  uint32_t dv;            // velocity change per profile tick (ACCEL / 1000), for controlled stops
  uint32_t v0sq4;         // 4 v0^2 and 8 a [steps/s, steps/s^2]: the ramps as (2v)^2 = 4 v0^2 + 8 a s,
  uint32_t a8;            // s = steps from the nearer end of the move
  int32_t target[6];
};

// Plans start -> target. Returns RBX1_OK, or RBX1_BAD_ARG if a joint would move 2^31 steps or more.
uint8_t plan_move(plan_block *b, const int32_t start[6], const int32_t target[6], uint16_t duration_ms);
// A gripper entry: servo pulse then a dwell.
void plan_gripper(plan_block *b, uint16_t pulse_us, uint16_t dwell_ms);

#endif
