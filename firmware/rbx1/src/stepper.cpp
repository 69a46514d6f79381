// stepper.cpp - stepper driver: step pulses from the Timer1 compare interrupt (16-bit Bresenham/DDA over segments
// of planned blocks) and the 1 kHz profile tick that ramps the velocity, prepares segments, runs on from one move
// into the next (look-ahead) and sequences the queue. Never driven by loop().
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

// A segment: at most 32767 dominant steps of one block, run by the step ISR's 16-bit Bresenham. A block of more
// dominant steps runs as several segments, each with the exact integer share of every joint's steps; the profile
// tick prepares the next one while the current one runs (the next block's first when the two join), and the ISR
// switches without a gap.
#define SEG_MAX 0x7FFFUL
struct seg_t {
  const plan_block *blk;  // the block it belongs to (0: at rest, base holds the positions)
  uint32_t k0;            // the block's dominant steps before this segment
  uint16_t m;             // dominant steps in the segment
  uint8_t dom;            // the dominant joint's bit: it steps on every tick
  uint8_t act;            // the other joints that step in this segment
  int16_t inc[RBX1_JOINTS];  // steps per joint in this segment
  int32_t base[RBX1_JOINTS]; // positions at the segment's start
  uint8_t dir;            // bit per joint: positive
  uint8_t dirbits;        // DIR outputs (dir with INVERT_DIR applied)
  uint8_t seq;            // the block's queue seq (plan_block.seq)
};
static seg_t segs[2];

// Step-ISR state: touched by st_step_isr(); by others while the step timer is stopped (the step interrupt cannot
// run then), or with interrupts off for a few bytes.
static struct {
  uint8_t waiting;       // a long interval is being served in chunks (wait_chunks of them left)
  uint8_t next;          // STEP mask of the coming step, computed one step ahead (so it leaves right after entry)
  uint8_t act, dom;      // of the current segment
  uint8_t cur;           // segs[cur] runs
  uint8_t ready;         // segs[cur ^ 1] is prepared: the ISR switches to it when the current one ends
  uint8_t running;       // step timer active
  uint8_t jog_mask;      // limit bit that ends a jog, 0 when not jogging
  uint8_t jog_level;     // ... when it reads this
  uint8_t jog_hit;
  uint8_t estop_seen;    // the step ISR saw the e-stop input (the profile tick latches it, even if brief)
  uint8_t gen;           // changes whenever the current segment changes (position readers retry on a change)
  uint8_t dirbits;       // DIR outputs now
  int16_t n16;           // dominant steps of the current segment
  uint16_t left;         // of them not yet output
  uint16_t iv16;         // step interval in timer ticks; 0: longer than 16 bits, then it is
  uint16_t iv_first;     // ... iv_first (0x8000..0xFFFF) plus iv_chunks times ST_CHUNK (written by the profile tick)
  uint16_t iv_chunks;
  uint16_t wait_chunks;  // ST_CHUNKs still to wait before the next step (long intervals)
  int16_t cnt16[RBX1_JOINTS]; // Bresenham: starts at m-1, minus inc each tick, plus m on a step
  int16_t inc16[RBX1_JOINTS];
} st;

// A homing jog runs this block.
static plan_block jog;

// Profile-tick state.
static struct {
  uint8_t entry;         // ENTRY_*
  plan_block *block;     // executing queue entry
  uint32_t v;            // 16.16 steps/s
  uint32_t v0, vc, dv;   // start/stop and cruise velocity, per-tick change of a controlled stop
  uint32_t entry_sq4, a8, accel_steps;  // the ramp up by position from the entry's velocity (planner.h)
  uint32_t exit_sq4, decel_steps;       // the ramp down of an entry run alone (else read from the block)
  uint8_t alone;         // runs from rest to rest: cruise vc_rest, exit at the stop rate, never joins the next
  uint16_t elapsed_ms;   // since the entry started (saturates)
  uint16_t duration_ms;
  uint8_t limits_start;  // limit inputs when the motion started: only new triggers are faults
  uint8_t stopping;      // controlled stop requested
  int32_t start[RBX1_JOINTS];
  uint16_t moves_done;
  uint16_t gripper_us;
} pf;

// At power-up, before hal_init() starts the interrupts that use this state: no interrupts-off window needed.
void st_init(void) {
  memset(&st, 0, sizeof(st));
  memset(&pf, 0, sizeof(pf));
  memset(segs, 0, sizeof(segs));
}

// A long interval: its first part now, then iv_chunks chunks (16-bit arithmetic only: fewer registers to save).
static inline __attribute__((always_inline)) void schedule_long(void) {
  st.wait_chunks = st.iv_chunks;
  st.waiting = 1;
  hal_step_timer_period(st.iv_first);
}

// One joint's Bresenham step for the coming tick, unrolled with a constant index so the AVR addresses its fields
// directly; joints that do not step in the segment cost one bit test.
#define ST_JOINT16(i)                                         \
  do {                                                        \
    if (act & (1u << (i))) {                                  \
      int16_t c = (int16_t)(st.cnt16[i] - st.inc16[i]);       \
      if (c < 0) {                                            \
        c = (int16_t)(c + n);                                 \
        mask |= (uint8_t)(1u << (i));                         \
      }                                                       \
      st.cnt16[i] = c;                                        \
    }                                                         \
  } while (0)

// The STEP mask of the tick after the one being output.
static inline __attribute__((always_inline)) uint8_t next_mask(void) {
  uint8_t mask = st.dom;
  const uint8_t act = st.act;
  if (act) {
    const int16_t n = st.n16;
    ST_JOINT16(0);
    ST_JOINT16(1);
    ST_JOINT16(2);
    ST_JOINT16(3);
    ST_JOINT16(4);
    ST_JOINT16(5);
  }
  return mask;
}

// Makes segment g the current one (ISR, or with the timer stopped): constant addresses, no pointer registers.
#define ST_LOAD(g)                                                                                   \
  do {                                                                                               \
    st.cur = (g);                                                                                    \
    st.left = segs[g].m;                                                                             \
    st.n16 = (int16_t)segs[g].m;                                                                     \
    st.dom = segs[g].dom;                                                                            \
    st.act = segs[g].act;                                                                            \
    const int16_t c0 = (int16_t)(segs[g].m - 1u);                                                    \
    st.inc16[0] = segs[g].inc[0]; st.cnt16[0] = c0;                                                  \
    st.inc16[1] = segs[g].inc[1]; st.cnt16[1] = c0;                                                  \
    st.inc16[2] = segs[g].inc[2]; st.cnt16[2] = c0;                                                  \
    st.inc16[3] = segs[g].inc[3]; st.cnt16[3] = c0;                                                  \
    st.inc16[4] = segs[g].inc[4]; st.cnt16[4] = c0;                                                  \
    st.inc16[5] = segs[g].inc[5]; st.cnt16[5] = c0;                                                  \
  } while (0)

// Time budget (16 MHz), measured with rbx1-avrsim's pin-level trace (tools/avrsim/timing.py): see
// firmware/README.md, Timing. Everything on the common path is 8 or 16 bits. The mask of this step was computed
// by the previous call, so the pulses leave a fixed few cycles after entry whatever the joint count; the e-stop
// input is sampled right before them. Positions need no per-step work (they follow from the segment and `left`,
// see st_position()). The STEP pulse lasts from hal_step_high() to hal_step_low(), over the next mask's
// computation.
void st_step_isr(void) {
  if (st.waiting) {
    if (--st.wait_chunks == 0) st.waiting = 0;
    hal_step_timer_period((uint16_t)ST_CHUNK);
    return;
  }
  const uint8_t mask = st.next;
  if (hal_estop_input()) {  // the profile tick latches the fault and flushes; here only pulses stop
    hal_step_timer_stop();
    st.running = 0;
    st.estop_seen = 1;
    return;
  }
  hal_step_high(mask);
  uint16_t left = (uint16_t)(st.left - 1u);
  st.left = left;
  if (left == 0) {
    if (!st.ready) {
      hal_step_timer_stop();
      st.running = 0;
      hal_step_low();
      return;
    }
    st.ready = 0;  // the next segment (of the block, or of the next move), prepared by the profile tick: no gap
    uint8_t dir;
    if (st.cur) {
      ST_LOAD(0);
      dir = segs[0].dirbits;
    } else {
      ST_LOAD(1);
      dir = segs[1].dirbits;
    }
    st.gen++;
    if (dir != st.dirbits) {  // a new move: DIR after this STEP's falling edge (the loads above kept it up long
      hal_step_low();         // enough), an interval before the next rise
      st.dirbits = dir;
      hal_dir_write(dir);
    }
  }
  const uint16_t iv = st.iv16;
  if (iv)
    hal_step_timer_period(iv);
  else
    schedule_long();
  st.next = next_mask();
  if (st.jog_mask && (uint8_t)((hal_limit_inputs() & st.jog_mask) != 0) == st.jog_level) {
    hal_step_timer_stop();  // on the switch: no further step
    st.running = 0;
    st.jog_hit = 1;
  }
  hal_step_low();
}

// Steps of a joint with `total` steps in n dominant ticks, after k of them (the Bresenham above, counters starting
// at n - 1, steps exactly floor(k * total / n)). No division at either end (a move's first segment, a whole move).
static uint32_t share(uint32_t k, uint32_t total, uint32_t n) {
  if (k >= n) return total;
  if (k == 0) return 0;
  if (n <= SEG_MAX) return (k * total) / n;  // < 2^30: 32-bit arithmetic
  return (uint32_t)(((uint64_t)k * total) / n);
}

// Positions of block b after k of its dominant steps.
static void block_positions(const plan_block *b, uint32_t k, int32_t out[RBX1_JOINTS]) {
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    int32_t rem = (int32_t)(b->steps[i] - share(k, b->steps[i], b->n));  // still to go before the target
    out[i] = (b->dir_positive & (1u << i)) ? b->target[i] - rem : b->target[i] + rem;
  }
}

// Positions now: the current segment's base plus its share of steps. Interrupts go off only to copy 4 bytes.
void st_position(int32_t out[RBX1_JOINTS]) {
  for (;;) {
    hal_irq_state s = hal_irq_save();
    uint8_t c = st.cur, g = st.gen;
    uint16_t left = st.left;
    hal_irq_restore(s);
    const seg_t *sg = &segs[c];
    uint16_t k = (uint16_t)(sg->m - left);
    for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
      int32_t d = sg->m ? (int32_t)share(k, (uint32_t)sg->inc[i], sg->m) : 0;
      out[i] = (sg->dir & (1u << i)) ? sg->base[i] + d : sg->base[i] - d;
    }
    s = hal_irq_save();
    uint8_t same = g == st.gen;
    hal_irq_restore(s);
    if (same) return;  // the segment changed meanwhile: read again
  }
}

// Publishes a change of the current segment to position readers.
static void bump_gen(void) {
  hal_irq_state s = hal_irq_save();
  st.gen++;
  hal_irq_restore(s);
}

// Makes the current positions the rest positions (steps stopped): segment with m = 0.
static void settle(void) {
  int32_t p[RBX1_JOINTS];
  st_position(p);
  st.ready = 0;
  seg_t *sg = &segs[st.cur];
  memcpy(sg->base, p, sizeof(p));
  sg->m = 0;
  sg->blk = 0;
  st.left = 0;
  bump_gen();
}

static uint32_t interval_of(uint32_t v) {
  uint32_t v8 = v >> 8;
  if (v8 == 0) v8 = 1;
  uint32_t i = ST_K / v8;
  return i < 2 ? 2 : i;
}

// The interval for the ISR: 16 bits, or 0 and the long value (interrupts off for a few bytes).
static void set_interval(uint32_t iv) {
  uint16_t chunks = 0, first = (uint16_t)iv;
  if (iv > 0xFFFFUL) {
    chunks = (uint16_t)((iv >> 15) - 1u);
    first = (uint16_t)(iv - (uint32_t)chunks * ST_CHUNK);  // 0x8000..0xFFFF
  }
  __asm__ __volatile__("" : : "r"(first), "r"(chunks) : "memory");  // computed before the window, never inside it
  hal_irq_state s = hal_irq_save();
  st.iv_first = first;
  st.iv_chunks = chunks;
  st.iv16 = chunks ? 0 : first;
  hal_irq_restore(s);
}

static uint8_t dir_bits(uint8_t dir_positive) {
  uint8_t invert = 0;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++)
    if (SETTING(i, RBX1_KEY_INVERT_DIR)) invert |= (uint8_t)(1u << i);
  return (uint8_t)((dir_positive ^ invert) & RBX1_ALL_JOINTS_MASK);
}

// Fills segs[g] with the dominant steps k0.. of block b (up to SEG_MAX of them).
static void prepare(uint8_t g, const plan_block *b, uint32_t k0) {
  seg_t *sg = &segs[g];
  uint32_t left = b->n - k0;
  uint16_t m = (uint16_t)(left > SEG_MAX ? SEG_MAX : left);
  sg->blk = b;
  sg->k0 = k0;
  sg->m = m;
  sg->dir = b->dir_positive;
  sg->dirbits = dir_bits(b->dir_positive);
  sg->seq = b->seq;
  sg->dom = 0;
  sg->act = 0;
  block_positions(b, k0, sg->base);
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    uint8_t bit = (uint8_t)(1u << i);
    uint32_t total = b->steps[i];
    uint16_t inc = (uint16_t)(share(k0 + m, total, b->n) - share(k0, total, b->n));
    sg->inc[i] = (int16_t)inc;
    if (total == b->n && !sg->dom)
      sg->dom = bit;  // steps on every tick
    else if (inc)
      sg->act |= bit;
  }
}

// The profile tick keeps the next segment ready: of a long block, or the first of the next move when the two join
// (the running one not alone, the next a move whose junction allows running on).
static void prepare_next(void) {
  if (st.ready || !st.running) return;
  const seg_t *sg = &segs[st.cur];
  const plan_block *b = sg->blk;
  if (!b) return;
  if (sg->k0 + sg->m < b->n) {
    prepare(st.cur ^ 1u, b, sg->k0 + sg->m);
  } else {
    if (pf.entry != ENTRY_QUEUE || b != pf.block || pf.alone) return;
    const plan_block *nb = queue_second();
    if (!nb || nb->kind != BLOCK_MOVE || nb->n == 0 || !(nb->joins & PLAN_JOINS)) return;
    prepare(st.cur ^ 1u, nb, 0);
  }
  st.ready = 1;  // one byte: the ISR sees all of it or nothing
}

// Loads block b's first segment (steps stopped) and starts the timer. Interrupts stay on: the step interrupt
// cannot run while its timer is stopped.
static void start_steps(const plan_block *b, uint32_t v) {
  st.dirbits = dir_bits(b->dir_positive);
  hal_dir_write(st.dirbits);  // set now; the first step comes one interval later
  st.ready = 0;
  uint8_t g = st.cur ^ 1u;
  prepare(g, b, 0);
  if (g)
    ST_LOAD(1);
  else
    ST_LOAD(0);
  st.next = next_mask();
  st.jog_hit = 0;
  set_interval(interval_of(v));
  st.waiting = st.iv16 == 0;
  st.wait_chunks = st.iv_chunks;
  bump_gen();
  hal_irq_state s = hal_irq_save();
  st.running = 1;
  hal_step_timer_start(st.iv_first);
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

// Two short interrupts-off windows instead of one long one: the pulses stop in the first; a profile tick between
// the two sees a stopped entry with `stopping` set and drops it as a truncated stop (never counts it as done).
void st_abort(void) {
  hal_irq_state s = hal_irq_save();
  hal_step_timer_stop();
  hal_step_low();
  st.running = 0;
  st.waiting = 0;
  pf.stopping = 1;
  hal_irq_restore(s);
  s = hal_irq_save();
  st.jog_mask = 0;
  pf.entry = ENTRY_NONE;
  pf.block = 0;
  pf.stopping = 0;
  queue_flush(0);
  hal_irq_restore(s);
  settle();  // before the flushed slots are written again
}

// The executing move decelerates; the moves it runs on into while it does are kept (so the stop never outruns the
// steps left), the others dropped at once: from the current velocity, at the smallest of their accelerations,
// twice the distance the stop needs plus two ticks of steps (the stop ramps by 1 ms ticks).
void st_stop(void) {
  hal_irq_state s = hal_irq_save();
  const plan_block *b = pf.entry == ENTRY_QUEUE ? pf.block : 0;
  uint32_t v = pf.v;
  uint8_t c = st.cur;
  uint16_t left = st.left;
  hal_irq_restore(s);
  uint8_t keep = b ? 1 : 0;
  if (b && b->kind == BLOCK_MOVE && b->n && segs[c].blk == b) {
    plan_block *q[QUEUE_SIZE];
    uint8_t n = queue_blocks(q);
    uint32_t v2 = v >> 15, a8 = b->a8;
    v2 *= v2;  // 4 v^2
    uint32_t have = b->n - (segs[c].k0 + (uint32_t)(segs[c].m - left)), extra = 2 + (v >> 25);
    for (uint8_t k = 1; k < n && q[k]->kind == BLOCK_MOVE && (q[k]->joins & PLAN_JOINS); k++) {
      uint32_t need = (v2 > b->stop_sq4 ? (v2 - b->stop_sq4) / a8 : 0) * 2 + extra;
      if (have >= need) break;
      if (q[k]->a8 < a8) a8 = q[k]->a8;
      have += q[k]->n;
      keep++;
    }
  }
  s = hal_irq_save();
  if (pf.entry == ENTRY_QUEUE && pf.block) {
    uint8_t first = queue_first_seq();
    if (pf.block->kind == BLOCK_MOVE && segs[st.cur].blk) {
      uint8_t at = (uint8_t)(segs[st.cur].seq - first);  // the ISR may have run on into the next move
      if (at < QUEUE_SIZE && at >= keep) keep = (uint8_t)(at + 1);
    }
    if (st.ready && (uint8_t)(segs[st.cur ^ 1u].seq - first) >= keep) st.ready = 0;
  } else {
    keep = 0;
  }
  queue_flush(keep);
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

// Only at rest (SET_POSITION in IDLE, homing between jogs).
void st_set_position(const int32_t p[RBX1_JOINTS]) {
  settle();
  memcpy(segs[st.cur].base, p, sizeof(segs[0].base));
  bump_gen();  // readers in the middle of a read start again
}

void st_set_joint_position(uint8_t joint, int32_t p) {
  settle();
  segs[st.cur].base[joint] = p;
  bump_gen();
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

// Called from the main loop at rest: the profile tick leaves the stepper alone until pf.entry says JOG.
void st_jog(uint8_t joint, uint8_t positive, uint32_t max_steps, uint32_t speed, uint8_t stop_level) {
  uint32_t v = speed * PLAN_V_ONE;
  settle();
  memset(&jog, 0, sizeof(jog));
  memcpy(jog.target, segs[st.cur].base, sizeof(jog.target));
  jog.steps[joint] = max_steps;
  jog.n = max_steps;
  jog.dir_positive = positive ? (uint8_t)(1u << joint) : 0;
  jog.target[joint] += positive ? (int32_t)max_steps : -(int32_t)max_steps;
  pf.block = 0;
  pf.v = pf.v0 = pf.vc = v;  // constant speed: no ramp (homing speeds are low)
  pf.dv = 0;
  pf.accel_steps = pf.decel_steps = 0;  // no ramps
  pf.alone = 1;
  pf.elapsed_ms = 0;
  pf.duration_ms = 0;
  pf.limits_start = hal_limit_inputs();
  st.jog_mask = (uint8_t)(1u << joint);
  st.jog_level = stop_level;
  start_steps(&jog, v);
  hal_irq_state s = hal_irq_save();
  pf.entry = ENTRY_JOG;
  hal_irq_restore(s);
}

uint8_t st_jog_hit(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t h = st.jog_hit;
  hal_irq_restore(s);
  return h;
}

static uint32_t sq4_of(uint32_t v) {
  uint32_t e = v >> 15;  // 2v in steps/s
  return e * e;
}

// The profile of block b entered at velocity v (16.16): the ramp up from v, cruise, the ramp down to the exit
// (the block's own look-ahead exit unless alone).
static void load_profile(const plan_block *b, uint32_t v, uint8_t alone) {
  pf.alone = alone;
  pf.v = v;
  pf.v0 = b->v0;
  pf.dv = b->dv;
  pf.a8 = b->a8;
  pf.vc = alone ? b->vc_rest : b->vc;
  uint32_t vc_sq4 = sq4_of(pf.vc);
  pf.entry_sq4 = sq4_of(v);
  pf.accel_steps = vc_sq4 > pf.entry_sq4 ? (vc_sq4 - pf.entry_sq4) / b->a8 + 1 : 0;
  pf.exit_sq4 = b->stop_sq4;
  pf.decel_steps = vc_sq4 > b->stop_sq4 ? (vc_sq4 - b->stop_sq4) / b->a8 + 1 : 0;
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
  pf.limits_start = hal_limit_inputs();
  if (!b->n) return;
  hal_irq_state s = hal_irq_save();
  uint32_t exit_sq4 = b->exit_sq4;
  hal_irq_restore(s);
  // From rest: alone when planned to stop at its end and duration_ms stretched it (its rest-to-rest cruise is
  // faster than n / duration_ms: run on from that, it could end early), so it keeps that profile and never joins
  // the next; else it may run on into moves that arrive while it runs.
  load_profile(b, b->v0, exit_sq4 <= b->stop_sq4 && b->vc_rest > b->vc);
  start_steps(b, b->v0);
}

// The ISR ran on from pf.block into the next move (the profile tick sees it within a tick): the finished move
// completed exactly at its target; the next continues from the current velocity.
static void advance(void) {
  hal_irq_state s = hal_irq_save();
  const plan_block *nb = segs[st.cur].blk;
  hal_irq_restore(s);
  plan_block *b = pf.block;
  if (!b || !nb || nb == b) return;
  pf.moves_done++;
  hal_entry_done(b->kind, pf.moves_done, b->target, pf.start, b->target, b->planned_ms, b->pulse_us);
  memcpy(pf.start, b->target, sizeof(pf.start));
  queue_pop();
  b = queue_first();  // == nb
  pf.block = b;
  pf.elapsed_ms = 0;
  pf.duration_ms = b->duration_ms;
  load_profile(b, pf.v, 0);
}

static void complete_entry(void) {
  plan_block *b = pf.block;
  int32_t end[RBX1_JOINTS];
  st_position(end);
  pf.moves_done++;
  hal_entry_done(b->kind, pf.moves_done, b->target, pf.start, end, b->planned_ms, b->pulse_us);
  settle();  // before the slot is popped and written again
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

// The trapezoid by position: 4 v^2 = 4 v_entry^2 + 8 a s from the entry and 4 v_exit^2 + 8 a s to the exit (s
// in steps; the first interval runs at the entry's velocity, the last at the exit's), capped at vc. The ramp down
// is position-based, so it ends at the exit velocity exactly where the steps run out. When the look-ahead raised
// the running move's exit (more moves arrived) the velocity rises by time at the acceleration, never in a jump.
// A controlled stop decelerates by time from the current velocity.
static void ramp(void) {
  hal_irq_state s = hal_irq_save();
  uint8_t c = st.cur;
  uint16_t l16 = st.left;
  hal_irq_restore(s);
  const seg_t *sg = &segs[c];
  const plan_block *b = pf.block ? pf.block : &jog;
  if (sg->blk != b) return;  // the ISR ran on into the next move: advance() on the next tick
  uint32_t done = sg->k0 + (uint32_t)(sg->m - l16), left = b->n - done;
  uint32_t exit_sq4 = pf.exit_sq4, decel = pf.decel_steps;
  if (!pf.alone) {
    s = hal_irq_save();
    exit_sq4 = b->exit_sq4;
    decel = b->decel_steps;
    hal_irq_restore(s);
  }
  // The interval set now is used after the next step (j = done + 1), between steps j and j + 1. Ramping down,
  // also look ahead by the steps of the coming tick.
  uint32_t ahead = 2 + (pf.v >> 26);  // + steps per 1 ms tick (v / 1024: no division on the AVR)
  uint32_t from_end = left > ahead ? left - ahead : 0;
  uint32_t up = done + 1, sq = 0xFFFFFFFFUL;
  uint8_t rising = 0;
  if (up < pf.accel_steps) {
    sq = pf.entry_sq4 + pf.a8 * up;
    rising = 1;
  }
  if (from_end < decel) {
    uint32_t dn = exit_sq4 + pf.a8 * from_end;
    if (dn < sq) {
      sq = dn;
      rising = 0;
    }
  }
  uint32_t v = pf.vc;
  if (sq != 0xFFFFFFFFUL) {
    v = isqrt32(sq) << 15;  // isqrt gives 2v in steps/s; 16.16 is v << 16
    if (v > pf.vc) v = pf.vc;
  }
  if (v < pf.v0) v = pf.v0;
  if (!rising && v > pf.v + pf.dv) v = pf.v + pf.dv;
  if (pf.stopping) {
    if (pf.v <= pf.v0 + pf.dv) {  // at the start/stop rate: stop here
      stop_steps();
      return;
    }
    if (v > pf.v - pf.dv) v = pf.v - pf.dv;
  }
  if (v == pf.v) return;  // cruising: the interval stands (saves the division)
  pf.v = v;
  // set_interval() keeps the division out of the interrupts-off window: an asm that reads the result cannot move
  // before it, and volatile asms (the cli) keep their order. Without that the compiler moved the division inside.
  set_interval(interval_of(v));
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
    uint8_t watched = (uint8_t)(RBX1_ALL_JOINTS_MASK & ~st.jog_mask);  // a homing jog's own switch is expected
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
    if (pf.entry == ENTRY_QUEUE) advance();
    prepare_next();
    ramp();
    return;
  }
  // Steps done (or none): jogs end now; queue entries wait out their minimum duration, unless stopping.
  if (pf.entry == ENTRY_JOG) {
    st.jog_mask = 0;
    settle();
    pf.entry = ENTRY_NONE;
    return;
  }
  if (pf.stopping) {  // a truncated entry is not completed
    settle();
    pf.entry = ENTRY_NONE;
    pf.block = 0;
    queue_flush(0);
    pf.stopping = 0;
    return;
  }
  if (pf.elapsed_ms >= pf.duration_ms) complete_entry();
}
