// queue.cpp - the motion queue ring buffer (single producer: main loop; single consumer: profile tick).
#include "queue.h"

#include <string.h>

#include "config.h"
#include "hal.h"

static plan_block blocks[QUEUE_SIZE];
static uint8_t head, tail, count;  // count is changed only with interrupts off
static uint8_t epoch, reserved_epoch;
static int32_t last_target[RBX1_JOINTS];
static uint8_t last_target_valid;  // 1: last_target holds it; KEPT: the kept entry's target (after a flush)
#define KEPT 2
static uint16_t accepted, flushed;

void queue_init(void) {
  head = tail = count = 0;
  epoch = reserved_epoch = 0;
  last_target_valid = 0;
  accepted = flushed = 0;
}

uint8_t queue_count(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t c = count;
  hal_irq_restore(s);
  return c;
}

uint8_t queue_free(void) { return (uint8_t)(QUEUE_SIZE - queue_count()); }

plan_block *queue_reserve(void) {
  hal_irq_state s = hal_irq_save();
  plan_block *b = count < QUEUE_SIZE ? &blocks[head] : 0;
  reserved_epoch = epoch;
  hal_irq_restore(s);
  return b;
}

uint8_t queue_commit(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t ok = reserved_epoch == epoch && count < QUEUE_SIZE;
  plan_block *b = &blocks[head];
  if (ok) {
    b->seq = (uint8_t)accepted;
    head = (uint8_t)((head + 1) % QUEUE_SIZE);
    count++;
    accepted++;
  }
  hal_irq_restore(s);
  // Outside the interrupts-off window (24 bytes would keep it 200 cycles): only the main loop writes last_target,
  // and a flush from the profile tick meanwhile leaves count 0, so queue_plan_start() does not use it.
  if (ok && b->kind == BLOCK_MOVE) {
    memcpy(last_target, b->target, sizeof(last_target));
    last_target_valid = 1;
  }
  return ok;
}

// Called between queue_reserve() and queue_commit(): a flush after this makes the commit fail, so the copy needs
// no interrupts-off window.
void queue_plan_start(int32_t out[RBX1_JOINTS], const int32_t current[RBX1_JOINTS]) {
  hal_irq_state s = hal_irq_save();
  const int32_t *from = count > 0 && last_target_valid ? last_target : current;
  if (count > 0 && last_target_valid == KEPT) from = blocks[(head + QUEUE_SIZE - 1) % QUEUE_SIZE].target;
  hal_irq_restore(s);
  memcpy(out, from, sizeof(last_target));
}

plan_block *queue_first(void) { return count ? &blocks[tail] : 0; }

plan_block *queue_second(void) { return count > 1 ? &blocks[(tail + 1) % QUEUE_SIZE] : 0; }

uint8_t queue_first_seq(void) { return blocks[tail].seq; }

const plan_block *queue_last(void) {
  hal_irq_state s = hal_irq_save();
  const plan_block *b = count ? &blocks[(head + QUEUE_SIZE - 1) % QUEUE_SIZE] : 0;
  hal_irq_restore(s);
  return b;
}

uint8_t queue_blocks(plan_block *out[QUEUE_SIZE]) {
  hal_irq_state s = hal_irq_save();
  uint8_t t = tail, c = count;
  hal_irq_restore(s);
  for (uint8_t k = 0; k < c; k++) out[k] = &blocks[(t + k) % QUEUE_SIZE];
  return c;
}

void queue_pop(void) {
  hal_irq_state s = hal_irq_save();
  if (count) {
    tail = (uint8_t)((tail + 1) % QUEUE_SIZE);
    count--;
  }
  hal_irq_restore(s);
}

void queue_flush(uint8_t keep) {
  hal_irq_state s = hal_irq_save();
  if (keep > count) keep = count;
  flushed = (uint16_t)(flushed + (count - keep));
  count = keep;
  head = (uint8_t)((tail + keep) % QUEUE_SIZE);
  epoch++;
  // Kept entries are moves (or the one executing entry): later moves plan from the newest one's target (read from
  // the entry, no copy in this window).
  last_target_valid = (keep && blocks[(head + QUEUE_SIZE - 1) % QUEUE_SIZE].kind == BLOCK_MOVE) ? KEPT : 0;
  hal_irq_restore(s);
}

uint16_t queue_accepted(void) {
  hal_irq_state s = hal_irq_save();
  uint16_t a = accepted;
  hal_irq_restore(s);
  return a;
}

uint16_t queue_flushed(void) {
  hal_irq_state s = hal_irq_save();
  uint16_t f = flushed;
  hal_irq_restore(s);
  return f;
}
