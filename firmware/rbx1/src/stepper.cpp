// stepper.cpp - stepper driver: step pulses from the Timer1 compare interrupt (Bresenham/DDA over a planned
// block) and the 1 kHz profile tick that ramps the velocity and sequences the queue. Never driven by loop().
#include "stepper.h"

#include <string.h>

#include "config.h"
#include "hal.h"
#include "planner.h"
#include "queue.h"
#include "rbx1_proto.h"
#include "settings.h"
#include "system.h"

// interval [2 MHz ticks] = STEP_TIMER_HZ / (v / 65536) = ST_K / (v >> 8)
#define ST_K (STEP_TIMER_HZ * 256UL)
#define ST_CHUNK ((uint32_t)0x8000)  // intervals above 16 bits are served in chunks of this many ticks

#define ENTRY_NONE 0
#define ENTRY_QUEUE 1  // a queue entry (move or gripper), completes into moves_done
#define ENTRY_JOG 2    // a homing jog

// Step-ISR state: touched only by st_step_isr(), or by others with interrupts off while the timer is stopped.
static struct {
  int32_t pos[6];
  int32_t counter[6];  // Bresenham: starts at n-1, minus inc each tick, plus n on a step
  uint32_t inc[6];     // steps of each joint in this block
  int16_t counter16[6];  // the same in 16 bits, used when n fits (most moves): half the work on the AVR
  int16_t inc16[6];
  uint16_t done16[6];  // steps done per joint in a small block; pos[] then holds the block's start
  uint8_t small;       // n < 32768: the 16-bit counters are in use
  uint8_t waiting;     // wait_rest != 0 (one byte to test in the common case)
  uint8_t dir;         // bit per joint: positive
  uint32_t n;          // dominant steps
  uint32_t left;       // dominant steps still to do
  uint32_t interval;   // current step interval (written by the profile tick)
  uint32_t wait_rest;  // ticks still to wait before the next step (long intervals)
  uint8_t running;     // step timer active
  uint8_t jog_mask;    // limit bit that ends a jog, 0 when not jogging
  uint8_t jog_level;   // ... when it reads this
  uint8_t jog_hit;
  uint8_t estop_seen;  // the step ISR saw the e-stop input (the profile tick latches it, even if brief)
} st;

// Profile-tick state.
static struct {
  uint8_t entry;         // ENTRY_*
  plan_block *block;     // executing queue entry
  uint32_t v;            // 16.16 steps/s
  uint32_t v0, vc, dv;   // start/stop and cruise velocity, per-tick change of a controlled stop
  uint32_t ramp_steps, v0sq4, a8;  // the ramps by position (planner.h)
  uint16_t elapsed_ms;   // since the entry started (saturates)
  uint16_t duration_ms;
  uint8_t limits_start;  // limit inputs when the motion started: only new triggers are faults
  uint8_t stopping;      // controlled stop requested
  int32_t start[6];
  uint16_t moves_done;
  uint16_t gripper_us;
} pf;

void st_init(void) {
  hal_irq_state s = hal_irq_save();
  memset(&st, 0, sizeof(st));
  memset(&pf, 0, sizeof(pf));
  hal_irq_restore(s);
}

// Next step in w ticks (w >= 2); long waits are split into 16-bit chunks.
static inline __attribute__((always_inline)) void schedule(uint32_t w) {
  if (w > 0xFFFFUL) {
    st.wait_rest = w - ST_CHUNK;
    st.waiting = 1;
    hal_step_timer_period((uint16_t)ST_CHUNK);
  } else {
    st.waiting = 0;
    hal_step_timer_period((uint16_t)w);
  }
}

// One joint's Bresenham step, unrolled with a constant index so the AVR addresses its fields directly.
// Small blocks (n < 32768) count 16-bit steps done per joint; others move the 32-bit position directly.
#define ST_JOINT16(i)                                         \
  do {                                                        \
    int16_t c = (int16_t)(st.counter16[i] - st.inc16[i]);     \
    if (c < 0) {                                              \
      c = (int16_t)(c + n);                                   \
      mask |= (uint8_t)(1u << (i));                           \
      st.done16[i]++;                                         \
    }                                                         \
    st.counter16[i] = c;                                      \
  } while (0)
#define ST_JOINT32(i)                                         \
  do {                                                        \
    int32_t c = st.counter[i] - (int32_t)st.inc[i];           \
    if (c < 0) {                                              \
      c += n;                                                 \
      mask |= (uint8_t)(1u << (i));                           \
      if (dir & (1u << (i)))                                  \
        st.pos[i]++;                                          \
      else                                                    \
        st.pos[i]--;                                          \
    }                                                         \
    st.counter[i] = c;                                        \
  } while (0)

// Time budget (16 MHz), measured under simavr (rbx1-avrsim): 316 cycles per interrupt with 1 joint stepping,
// 345 with 3, 387 with 6 (65 cycles per step; 16-bit counters, moves under 32768 steps), 577 with 6 joints on
// the 32-bit path. The 30 kHz aggregate target (6 joints x 5 kHz) costs 5k x 387 = 1.9 M cycles/s, 12% of the
// CPU; 6 joints at the 20 kHz MAX_SPEED limit (120 kHz aggregate) 48%, and still exact. The e-stop input is read first, so no
// pulse leaves after it is seen. Per-block Bresenham increments are precomputed; the velocity ramp arrives from
// the profile tick as a ready interval. The STEP pulse lasts from hal_step_high() to hal_step_low() (>= 2.5 us).
void st_step_isr(void) {
  if (st.waiting) {
    schedule(st.wait_rest);
    return;
  }
  if (hal_estop_input()) {  // the profile tick latches the fault and flushes; here only pulses stop
    hal_step_timer_stop();
    st.running = 0;
    st.estop_seen = 1;
    return;
  }
  uint8_t mask = 0;
  if (st.small) {
    const int16_t n = (int16_t)st.n;
    ST_JOINT16(0);
    ST_JOINT16(1);
    ST_JOINT16(2);
    ST_JOINT16(3);
    ST_JOINT16(4);
    ST_JOINT16(5);
  } else {
    const int32_t n = (int32_t)st.n;
    const uint8_t dir = st.dir;
    ST_JOINT32(0);
    ST_JOINT32(1);
    ST_JOINT32(2);
    ST_JOINT32(3);
    ST_JOINT32(4);
    ST_JOINT32(5);
  }
  hal_step_high(mask);
  st.left--;
  if (st.jog_mask && (uint8_t)((hal_limit_inputs() & st.jog_mask) != 0) == st.jog_level) {
    st.jog_hit = 1;
    st.left = 0;
  }
  if (st.left == 0) {
    hal_step_timer_stop();
    st.running = 0;
  } else {
    schedule(st.interval);
  }
  hal_step_low();
}

// Position of joint i (interrupts off).
static int32_t pos_of(uint8_t i) {
  int32_t p = st.pos[i];
  if (st.small) p += (st.dir & (1u << i)) ? (int32_t)st.done16[i] : -(int32_t)st.done16[i];
  return p;
}

// Makes pos[] the current positions again (interrupts off, timer stopped).
static void fold_positions(void) {
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    st.pos[i] = pos_of(i);
    st.done16[i] = 0;
  }
  st.small = 0;
}

static uint32_t interval_of(uint32_t v) {
  uint32_t v8 = v >> 8;
  if (v8 == 0) v8 = 1;
  uint32_t i = ST_K / v8;
  return i < 2 ? 2 : i;
}

// Loads step-ISR state for n dominant steps (interrupts off, timer stopped) and starts the timer.
static void start_steps(const uint32_t steps[6], uint8_t dir_positive, uint32_t n, uint32_t v) {
  uint8_t invert = 0;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++)
    if (SETTING(i, RBX1_KEY_INVERT_DIR)) invert |= (uint8_t)(1u << i);
  hal_irq_state s = hal_irq_save();
  hal_dir_write((uint8_t)((dir_positive ^ invert) & 0x3F));  // set now; the first step comes one interval later
  fold_positions();
  st.small = n < 0x8000UL;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    st.inc[i] = steps[i];
    st.counter[i] = (int32_t)(n - 1);
    st.inc16[i] = (int16_t)steps[i];  // meaningful only when small (then every steps[i] <= n < 32768)
    st.counter16[i] = (int16_t)(n - 1);
  }
  st.dir = dir_positive;
  st.n = n;
  st.left = n;
  st.interval = interval_of(v);
  st.jog_hit = 0;
  st.running = 1;
  uint32_t first = st.interval;
  if (first > 0xFFFFUL) {
    st.wait_rest = first - ST_CHUNK;
    st.waiting = 1;
    first = ST_CHUNK;
  } else {
    st.waiting = 0;
  }
  hal_step_timer_start((uint16_t)first);
  hal_irq_restore(s);
}

static void stop_steps(void) {
  hal_irq_state s = hal_irq_save();
  hal_step_timer_stop();
  hal_step_low();
  st.running = 0;
  st.waiting = 0;
  hal_irq_restore(s);
}

static uint8_t steps_running(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t r = st.running;
  hal_irq_restore(s);
  return r;
}

void st_abort(void) {
  hal_irq_state s = hal_irq_save();
  stop_steps();
  st.jog_mask = 0;
  pf.entry = ENTRY_NONE;
  pf.block = 0;
  pf.stopping = 0;
  queue_flush(0);
  hal_irq_restore(s);
}

void st_stop(void) {
  hal_irq_state s = hal_irq_save();
  queue_flush(pf.entry == ENTRY_QUEUE);
  pf.stopping = 1;
  hal_irq_restore(s);
}

uint8_t st_stopping(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t b = pf.stopping;
  hal_irq_restore(s);
  return b;
}

uint8_t st_busy(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t b = pf.entry != ENTRY_NONE || st.running;
  hal_irq_restore(s);
  return b;
}

void st_position(int32_t out[6]) {
  hal_irq_state s = hal_irq_save();
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) out[i] = pos_of(i);
  hal_irq_restore(s);
}

// Only at rest (SET_POSITION in IDLE, homing between jogs).
void st_set_position(const int32_t p[6]) {
  hal_irq_state s = hal_irq_save();
  fold_positions();
  memcpy(st.pos, p, sizeof(st.pos));
  hal_irq_restore(s);
}

void st_set_joint_position(uint8_t joint, int32_t p) {
  hal_irq_state s = hal_irq_save();
  fold_positions();
  st.pos[joint] = p;
  hal_irq_restore(s);
}

uint16_t st_moves_done(void) {
  hal_irq_state s = hal_irq_save();
  uint16_t m = pf.moves_done;
  hal_irq_restore(s);
  return m;
}

uint16_t st_gripper_us(void) {
  hal_irq_state s = hal_irq_save();
  uint16_t g = pf.gripper_us;
  hal_irq_restore(s);
  return g;
}

void st_jog(uint8_t joint, uint8_t positive, uint32_t max_steps, uint32_t speed, uint8_t stop_level) {
  uint32_t steps[6] = {0, 0, 0, 0, 0, 0};
  steps[joint] = max_steps;
  uint32_t v = speed * PLAN_V_ONE;
  hal_irq_state s = hal_irq_save();
  pf.entry = ENTRY_JOG;
  pf.block = 0;
  pf.v = pf.v0 = pf.vc = v;  // constant speed: no ramp (homing speeds are low)
  pf.dv = 0;
  pf.ramp_steps = 0;  // no ramps
  pf.elapsed_ms = 0;
  pf.duration_ms = 0;
  pf.limits_start = hal_limit_inputs();
  st.jog_mask = (uint8_t)(1u << joint);
  st.jog_level = stop_level;
  start_steps(steps, positive ? (uint8_t)(1u << joint) : 0, max_steps, v);
  hal_irq_restore(s);
}

uint8_t st_jog_hit(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t h = st.jog_hit;
  hal_irq_restore(s);
  return h;
}

// Starts the oldest queue entry.
static void start_entry(plan_block *b) {
  pf.entry = ENTRY_QUEUE;
  pf.block = b;
  pf.elapsed_ms = 0;
  pf.duration_ms = b->duration_ms;
  st_position(pf.start);
  if (b->kind == BLOCK_GRIPPER) {
    pf.gripper_us = b->pulse_us;
    hal_servo_write(b->pulse_us);
    return;
  }
  pf.v = b->v0;
  pf.v0 = b->v0;
  pf.vc = b->vc;
  pf.dv = b->dv;
  pf.ramp_steps = b->ramp_steps;
  pf.v0sq4 = b->v0sq4;
  pf.a8 = b->a8;
  pf.limits_start = hal_limit_inputs();
  if (b->n) start_steps(b->steps, b->dir_positive, b->n, b->v0);
}

static void complete_entry(void) {
  plan_block *b = pf.block;
  int32_t end[6];
  st_position(end);
  pf.moves_done++;
  hal_entry_done(b->kind, pf.moves_done, b->target, pf.start, end, b->planned_ms, b->pulse_us);
  pf.entry = ENTRY_NONE;
  pf.block = 0;
  queue_pop();
}

// Integer square root (bit by bit: no division, ~16 iterations on the AVR).
static uint32_t isqrt32(uint32_t x) {
  uint32_t r = 0, bit = 1UL << 30;
  while (bit > x) bit >>= 2;
  while (bit) {
    if (x >= r + bit) {
      x -= r + bit;
      r = (r >> 1) + bit;
    } else {
      r >>= 1;
    }
    bit >>= 2;
  }
  return r;
}

// The trapezoid by position: v^2 = v0^2 + 2 a s, s = steps from the nearer end (the first and the last interval
// run at v0), capped at vc. Position-based, so the ramp-down ends at rest exactly where the steps run out. A
// controlled stop decelerates by time from the current velocity instead.
static void ramp(void) {
  hal_irq_state s = hal_irq_save();
  uint32_t done = st.n - st.left, left = st.left;
  hal_irq_restore(s);
  uint32_t v;
  if (pf.stopping) {
    v = pf.v;
    if (v <= pf.v0 + pf.dv) {  // at the start/stop rate: stop here
      stop_steps();
      return;
    }
    v -= pf.dv;
  } else {
    // The interval set now is used after the next step (j = done + 1), between steps j and j + 1:
    // s = min(j, n - 1 - j). Ramping down, also look ahead by the steps of the coming tick.
    uint32_t ahead = 2 + (pf.v >> 26);  // + steps per 1 ms tick (v / 1024: no division on the AVR)
    uint32_t from_end = left > ahead ? left - ahead : 0;
    uint32_t d = done + 1 < from_end ? done + 1 : from_end;
    if (d >= pf.ramp_steps) {
      v = pf.vc;
    } else {
      v = isqrt32(pf.v0sq4 + pf.a8 * d) << 15;  // isqrt gives 2v in steps/s; 16.16 is v << 16
      if (v > pf.vc) v = pf.vc;
      if (v < pf.v0) v = pf.v0;
    }
  }
  if (v == pf.v) return;  // cruising: the interval stands (saves the division)
  pf.v = v;
  uint32_t iv = interval_of(v);
  s = hal_irq_save();
  st.interval = iv;
  hal_irq_restore(s);
}

// Time budget: while the velocity changes, an integer square root and a 32-bit division (~1300 cycles); cruising
// or idle, ~100 cycles. At 1 kHz that is under 9% of the CPU, and the step interrupt preempts it on the AVR.
void st_profile_isr(void) {
  uint8_t limits = hal_limit_inputs();
  uint8_t seen = st.estop_seen;  // an 8-bit read is atomic; the step ISR only ever sets it
  if (seen) st.estop_seen = 0;
  if (hal_estop_input() || seen) {
    if (!(sys.faults & RBX1_FAULT_ESTOP_INPUT)) sys_set_fault(RBX1_FAULT_ESTOP_INPUT);
    if (pf.entry != ENTRY_NONE || queue_count()) st_abort();
    return;
  }
  uint8_t moving = steps_running();
  if (moving) {
    uint8_t watched = (uint8_t)(0x3F & ~st.jog_mask);  // a homing jog's own switch is expected
    if ((limits & ~pf.limits_start) & watched) {
      sys_set_fault(RBX1_FAULT_LIMIT_HIT);
      st_abort();
      return;
    }
  }
  if (sys_faulted()) {
    if (pf.entry != ENTRY_NONE || queue_count()) st_abort();
    return;
  }
  if (pf.entry == ENTRY_NONE) {
    if (pf.stopping) {  // nothing (left) to stop: at rest
      pf.stopping = 0;
      return;
    }
    plan_block *b = queue_first();
    if (b) start_entry(b);
    return;
  }
  if (pf.elapsed_ms != 0xFFFF) pf.elapsed_ms++;
  if (moving) {
    ramp();
    return;
  }
  // Steps done (or none): jogs end now; queue entries wait out their minimum duration, unless stopping.
  if (pf.entry == ENTRY_JOG) {
    st.jog_mask = 0;
    pf.entry = ENTRY_NONE;
    return;
  }
  if (pf.stopping) {  // a truncated entry is not completed
    pf.entry = ENTRY_NONE;
    pf.block = 0;
    queue_flush(0);
    pf.stopping = 0;
    return;
  }
  if (pf.elapsed_ms >= pf.duration_ms) complete_entry();
}
