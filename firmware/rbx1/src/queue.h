// queue.h - the motion queue: a ring of planned MOVE and GRIPPER entries, filled by the main loop and consumed
// by the stepper's profile tick. The entry being executed stays in the queue until it completes.
#ifndef RBX1_QUEUE_H
#define RBX1_QUEUE_H

#include <stdint.h>

#include "config.h"
#include "planner.h"

void queue_init(void);
// Entries waiting or executing.
uint8_t queue_count(void);
// Room for new entries (STATUS.queue_free).
uint8_t queue_free(void);
// The slot to fill next, or 0 when full. Not visible to the stepper until queue_commit().
plan_block *queue_reserve(void);
// Publishes the reserved slot. Returns 0 (and drops it) if the queue was flushed since queue_reserve().
uint8_t queue_commit(void);
// Position the next MOVE starts from: the last queued move's target, or `current` when the queue is empty.
void queue_plan_start(int32_t out[RBX1_JOINTS], const int32_t current[RBX1_JOINTS]);
// Oldest entry, or 0 (stepper side).
plan_block *queue_first(void);
// The entry after the oldest, or 0 (stepper side: the move it may run on into).
plan_block *queue_second(void);
// The newest entry, or 0 (main loop, between queue_reserve() and queue_commit(): the junction's previous move).
const plan_block *queue_last(void);
// Pointers to the entries, oldest first (main loop: the look-ahead). Returns their number.
uint8_t queue_blocks(plan_block *out[QUEUE_SIZE]);
// Seq (plan_block.seq) of the oldest entry (stepper side).
uint8_t queue_first_seq(void);
// Removes the oldest entry (stepper side, when it completes).
void queue_pop(void);
// Drops entries but the oldest `keep` (the executing one, and those a controlled stop runs through).
// Interrupt-safe.
void queue_flush(uint8_t keep);
// Entries committed and entries dropped without completing, since power-up (STATUS.moves_accepted and
// moves_flushed; both wrap at 65536). accepted = moves_done + flushed + queue_count() whenever interrupts are off.
uint16_t queue_accepted(void);
uint16_t queue_flushed(void);

#endif
