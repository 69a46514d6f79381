// planner.h - turns a MOVE into a coordinated block (per-joint step counts for the Bresenham/DDA, the dominant
// joint's speed and acceleration limits within every joint's MAX_SPEED and ACCEL), and the look-ahead over the
// queue: junction speeds between consecutive moves and entry/exit speeds recomputed as moves arrive (GRBL-style).
#ifndef RBX1_PLANNER_H
#define RBX1_PLANNER_H

#include <stdint.h>

#include "rbx1_messages.h"

#define BLOCK_MOVE 0
#define BLOCK_GRIPPER 1

// Velocities are 16.16 fixed point steps/s: 1 step/s = 65536 (enough for 20000 steps/s in 32 bits). A velocity is
// always the rate of the block's dominant joint (the largest joint rate), which is continuous across junctions.
// Squared speeds are kept as 4 v^2 [(steps/s)^2] (the stepper's integer square root gives 2v).
#define PLAN_V_ONE 65536UL

// plan_block.joins
#define PLAN_JOINS 1        // runs on from the previous queue entry without stopping (the junction rule allows it)
#define PLAN_NEVER_JOINS 2  // too short to run on (under two profile ticks at its stop rate): stops at both ends

// plan_block.back_sq4 of an entry no backward pass has reached yet (above any 4 v^2 the planner computes)
#define PLAN_UNPLANNED 0xFFFFFFFFUL

struct plan_block {
  uint8_t kind;           // BLOCK_MOVE or BLOCK_GRIPPER
  uint8_t dir_positive;   // bit per joint: moving towards larger step counts
  uint8_t joins;          // PLAN_JOINS, PLAN_NEVER_JOINS or 0
  uint8_t seq;            // low byte of the queue's accepted counter at commit (the stepper's segments name it)
  uint16_t duration_ms;   // minimum time of the entry: the MOVE's duration_ms or the gripper's dwell
  uint16_t planned_ms;    // the profile's own time from rest to rest (for the move log)
  uint16_t pulse_us;      // gripper pulse
  uint32_t steps[RBX1_JOINTS]; // |target - start| per joint
  uint32_t n;             // dominant joint's steps (the DDA's tick count)
  uint32_t v0;            // start/stop rate (the first step's rate from rest)
  uint32_t vc;            // nominal velocity when joined: the fastest the limits allow, at most n / duration_ms
  uint32_t vc_rest;       // cruise of the block run alone from rest to rest, stretched to end by duration_ms
  uint32_t dv;            // velocity change per profile tick (a / 1000), for controlled stops
  uint32_t a8;            // 8 a [steps/s^2]: along a ramp 4 v^2 changes by a8 per step (set with the entry)
  uint32_t stop_sq4;      // 4 v0^2
  uint32_t vc_sq4;        // 4 vc^2
  uint32_t a8_full;       // 8 a at every joint's ACCEL (a8 is that less the bend's share at the entry speed)
  uint32_t span_sq4;      // a8_full * n (saturated): how much 4 v^2 can change over the whole block at most
  float bend8;            // the bend's share: a8 = a8_full - bend8 * entry_sq4 (0 when it does not join)
  float keep;             // 1 / (1 + bend8 n): the backward pass's entry from its exit (E <= (exit + span) keep)
  uint32_t max_entry_sq4; // junction limit with the previous entry (stop_sq4 when it does not join)
  uint32_t back_sq4;      // the backward pass's exit (what the entries after it allow), kept for the next pass
  // Look-ahead results, changed by planner_recalculate() while the entry waits or runs (interrupts off around
  // each pair): 4 v^2 at entry and exit, and the steps of the ramp from vc down to the exit; a8 and dv with the
  // entry (the stepper reads them when the entry starts).
  uint32_t entry_sq4;
  uint32_t exit_sq4;
  uint32_t decel_steps;
  int32_t target[RBX1_JOINTS];
};

// Plans start -> target. prev: the queue's last entry (0 when the queue is empty), for the junction limit.
// Returns RBX1_OK, or RBX1_BAD_ARG if a joint would move 2^31 steps or more.
uint8_t plan_move(plan_block *b, const int32_t start[RBX1_JOINTS], const int32_t target[RBX1_JOINTS],
                  uint16_t duration_ms, const plan_block *prev);
// A gripper entry: servo pulse then a dwell.
void plan_gripper(plan_block *b, uint16_t pulse_us, uint16_t dwell_ms);
// The look-ahead passes over the queue after a commit: backward from the last entry (which ends at its stop rate)
// and forward from the oldest (which may be running: its exit is only ever raised, see stepper.cpp), each cut
// short where the previous passes' result stands.
void planner_recalculate(void);
// Drops what the previous passes kept (back_sq4): the next pass runs over the whole queue (the test that compares
// the cut-short passes with the full ones; a firmware that never calls it does not contain it).
void planner_forget(void);
// A commit marks the look-ahead stale; the main loop recalculates after the link has answered what it read, once
// for all the moves committed meanwhile (a filled gap can release seven). Until then a new entry keeps the exits
// it was committed with (stops at both ends), which is always safe.
void planner_mark_stale(void);
void planner_poll(void);

#endif
