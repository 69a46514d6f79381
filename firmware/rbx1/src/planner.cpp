// planner.cpp - coordinated move planning: dominant-joint trapezoid scaled so every joint stays in its limits, and
// the look-ahead that joins consecutive moves (junction limits, backward and forward passes).
#include "planner.h"

#include <math.h>
#include <string.h>

#include "config.h"
#include "hal.h"
#include "queue.h"
#include "rbx1_proto.h"
#include "settings.h"

static uint32_t to_fixed(float v) {
  float f = v * (float)PLAN_V_ONE;
  if (f < 1.0f) return 1;
  if (f > 4.0e9f) return 4000000000UL;
  return (uint32_t)f;
}

// The time the stepper takes for the profile (an upper bound, so an entry never outlasts its planned time): the
// first interval runs at v0 (as from rest), the others at v(s) = sqrt(v0^2 + 2 a s) on the ramps (s = steps from
// the nearer end, below `ramp` steps) and at vc in between. 1/v is convex, so each ramp's sum over s = 1..ramp-1 is
// at most the integral of 1/v from 1/2 to ramp - 1/2. The ramp-down looks ahead by the v/1024 steps of a tick
// (at most ln(vc/v0)/1024 s more), and the 1 ms profile tick adds at most a tick of lag to the ramp-up. No
// interval is slower than v0, so n/v0 bounds short moves more tightly.
static float profile_s(float n, float ramp, float v0, float vc, float a) {
  float slowest = n / v0;
  if (ramp < 1.0f) return 1.0f / v0 + (n - 1.0f) / vc;  // no ramp: v0 for the first step, vc for the rest
  float v0sq = v0 * v0;
  float g = ramp >= 2.0f ? (sqrtf(v0sq + 2.0f * a * (ramp - 0.5f)) - sqrtf(v0sq + a)) / a : 0.0f;
  float t = 2.0f / v0 + 2.0f * g + (n - 2.0f * ramp) / vc + logf(vc / v0) / 1024.0f;
  return (t < slowest ? t : slowest) + 0.002f;
}

// Cruise velocity v of a profile taking T s: n/v + v/a = T (the smaller root).
static float stretch_v(float n, float a, float T) {
  float disc = a * a * T * T - 4.0f * a * n;
  return (a * T - sqrtf(disc > 0 ? disc : 0)) * 0.5f;
}

// Start/stop rate and ramp length for cruise velocity vc; returns the profile's time (profile_s).
static float shape(float fn, uint32_t n, float vc, float a, float *v0_out, uint32_t *ramp_out) {
  // The first step comes after sqrt(2/a) s, as from rest under constant acceleration; stop from the same rate.
  float v0 = sqrtf(a * 0.5f);
  if (v0 > vc) v0 = vc;
  float ramp = (vc * vc - v0 * v0) / (2.0f * a);
  uint32_t ramp_steps = (uint32_t)(ramp + 0.5f);
  if (ramp_steps > n / 2) ramp_steps = n / 2;
  *v0_out = v0;
  *ramp_out = ramp_steps;
  return profile_s(fn, (float)ramp_steps, v0, vc, a);
}

static uint32_t sq4_of(float v) {
  float f = 4.0f * v * v + 0.5f;
  return f > 4.0e9f ? 4000000000UL : (uint32_t)f;
}

// 8 a of block b entered at 4 v^2 = entry_sq4 (the bend's share taken off).
static uint32_t a8_at(const plan_block *b, uint32_t entry_sq4) {
  if (b->bend8 <= 0.0f) return b->a8_full;
  float loss = b->bend8 * (float)entry_sq4;
  return loss < (float)b->a8_full ? b->a8_full - (uint32_t)loss : 1;
}

// The ramps' a8 and the controlled stop's dv (interrupts off for the 8 bytes: the stepper reads them at a start).
static void set_accel(plan_block *b, uint32_t a8) {
  if (a8 == 0) a8 = 1;
  if (b->a8 == a8) return;
  // dv = a PLAN_V_ONE / PROFILE_TICK_HZ = 8.192 a8 / 8: 131 / 16 is 0.05% below, never a faster stop than a.
  uint32_t dv = (a8 * 131UL) >> 4;
  if (dv == 0) dv = 1;
  hal_irq_state s = hal_irq_save();
  b->a8 = a8;
  b->dv = dv;
  hal_irq_restore(s);
}

static uint32_t add_sat(uint32_t a, uint32_t b) { return a + b < a ? 0xFFFFFFFFUL : a + b; }

// The junction rule (firmware/README.md, Look-ahead): at a junction the dominant rate v is continuous, so joint i
// changes its velocity by v * d_i, d_i = |u_i - w_i| (u, w: its steps per dominant step in the two moves, signed).
// Each joint may jump by as much as a motor at ACCEL_i follows lagging at most JUNCTION_LAG_STEPS behind (config.h:
// the jump's lag is dv^2 / (2 ACCEL_i)), and by no more than ACCEL_i allows over the shorter move's time n/v
// (junctions every few steps, as on a curve, then average out within ACCEL):
// v d_i <= sqrt(2 ACCEL_i JUNCTION_LAG_STEPS) and v^2 d_i <= ACCEL_i * min(n, n').
// The junction speed is the largest v within those and both moves' nominal speeds. The moves join when that is at
// least both stop rates, each move can ramp between its stop rate and it, and the joints would join at the stop
// rates with jumps of at most their start rates sqrt(ACCEL_i / 2) (v d_i <= sqrt(ACCEL_i / 2): a reversal or a
// corner that sharp ends at rest, as a start from rest is the largest jump a joint makes there). A move that
// duration_ms stretched (plan_move) joins only at its whole cruise rate n / duration_ms.
// sqrt(ACCEL / 2) / sqrt(2 ACCEL JUNCTION_LAG_STEPS): the start rate's share of the lag bound.
static const float kStartOverJump = 0.5f / sqrtf((float)JUNCTION_LAG_STEPS);

// The bend's share (firmware/README.md, Look-ahead): joint i's jump at the junction, spread over the shorter move,
// adds v^2 d_i / min(n, n') to the acceleration of its ramp share, w_i a, so the move ramps at
// a(v) = min_i (ACCEL_i - v^2 d_i / min(n, n')) / w_i after entering at v. The passes take the chord of that concave
// function from v = 0 to the junction limit (a8 = a8_full - bend8 * 4 v^2, never above it), and the curve bound
// leaves at least kRampShare of a to the ramps at the limit, so that a bend never stalls them:
// v^2 d_i <= (ACCEL_i - w_i kRampShare a) min(n, n'). Sets b->bend8.
static const float kRampShare = 0.25f;

static void junction(plan_block *b, const plan_block *p, float vc, uint8_t stretched, float amax) {
  b->joins = 0;
  b->max_entry_sq4 = b->stop_sq4;
  if (!p || p->kind != BLOCK_MOVE || p->n == 0 || b->n == 0 || (p->joins & PLAN_NEVER_JOINS)) return;
  float vj = (float)p->vc / (float)PLAN_V_ONE;
  if (vc < vj) vj = vc;
  float vstart = vj;  // the same with jumps of at most the start rate: whether the moves join at all
  const float pn = (float)p->n, bn = (float)b->n, nmin = pn < bn ? pn : bn, per_n = 1.0f / nmin;
  float bend[RBX1_JOINTS];  // d_i / min(n, n')
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    uint8_t bit = (uint8_t)(1u << i);
    float u = (float)p->steps[i] / pn, w = (float)b->steps[i] / bn;
    if (!(p->dir_positive & bit)) u = -u;
    if (!(b->dir_positive & bit)) w = -w;
    float d = fabsf(u - w);
    bend[i] = d * per_n;
    if (d * vj > 0.0f) {
      float acc = (float)SETTING(i, RBX1_KEY_ACCEL);
      // jump: the largest v within the lag bound (the start rate's bound is a constant share of it: no second sqrtf)
      float jump = sqrtf(acc * (2.0f * JUNCTION_LAG_STEPS)) / d;
      float curve = sqrtf((acc - fabsf(w) * kRampShare * amax) / bend[i]);
      if (jump < vj) vj = jump;
      if (curve < vj) vj = curve;
      if (jump * kStartOverJump < vstart) vstart = jump * kStartOverJump;
    }
  }
  // A move duration_ms stretched joins only where it keeps its cruise n / duration_ms from the junction on: slowed
  // there, its ramp would fall outside duration_ms, while from rest it keeps its ramps inside (runs alone).
  if (stretched && vj < 0.999f * vc) return;
  uint32_t sq = sq4_of(vj);
  uint32_t floor = p->stop_sq4 > b->stop_sq4 ? p->stop_sq4 : b->stop_sq4;
  // A junction that jumps by more than the start rate even at the stop rate (a reversal, a sharp corner) stops.
  if (sq4_of(vstart) < floor || sq < floor || add_sat(b->stop_sq4, b->span_sq4) < floor || add_sat(p->stop_sq4, p->span_sq4) < floor) return;
  b->joins = PLAN_JOINS;
  b->max_entry_sq4 = sq;
  float a = amax, v2 = vj * vj;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    if (b->steps[i] == 0) continue;
    float left = ((float)SETTING(i, RBX1_KEY_ACCEL) - v2 * bend[i]) * bn / (float)b->steps[i];
    if (left < a) a = left;
  }
  b->bend8 = (amax - a) * 2.0f / v2;  // 8 (amax - a) per 4 v^2
  b->keep = 1.0f / (1.0f + b->bend8 * bn);
}

uint8_t plan_move(plan_block *b, const int32_t start[RBX1_JOINTS], const int32_t target[RBX1_JOINTS],
                  uint16_t duration_ms, const plan_block *prev) {
  memset(b, 0, sizeof(*b));
  b->kind = BLOCK_MOVE;
  b->duration_ms = duration_ms;
  memcpy(b->target, target, sizeof(b->target));
  uint32_t n = 0;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    int64_t d = (int64_t)target[i] - (int64_t)start[i];
    if (d >= 0x80000000LL || d <= -0x80000000LL) return RBX1_BAD_ARG;
    if (d > 0) b->dir_positive |= (uint8_t)(1u << i);
    b->steps[i] = (uint32_t)(d < 0 ? -d : d);
    if (b->steps[i] > n) n = b->steps[i];
  }
  b->n = n;
  b->planned_ms = duration_ms;
  b->back_sq4 = PLAN_UNPLANNED;
  if (n == 0) return RBX1_OK;  // nothing to step: the entry is a dwell of duration_ms (and a stop)

  // Dominant-joint limits: joint i moves steps[i]/n as fast as the dominant one, so its own limits scale up.
  float fn = (float)n, vmax = 1e30f, amax = 1e30f;
  for (uint8_t i = 0; i < RBX1_JOINTS; i++) {
    if (b->steps[i] == 0) continue;
    float r = fn / (float)b->steps[i];
    float v = (float)SETTING(i, RBX1_KEY_MAX_SPEED) * r, a = (float)SETTING(i, RBX1_KEY_ACCEL) * r;
    if (v < vmax) vmax = v;
    if (a < amax) amax = a;
  }
  // Fastest profile: cruise at vmax, or a triangle peaking where ramp-up and ramp-down meet (v^2/a = n).
  float vc = sqrtf(amax * fn);
  if (vmax < vc) vc = vmax;
  // Joined to its neighbours the move cruises at most at n / duration_ms: never shorter than duration_ms.
  // The cruise interval is a whole number of step-timer ticks, rounded up, so the stepper's truncated intervals
  // never run it faster.
  float T = (float)duration_ms * 0.001f, vjoin = vmax;
  if (T > 0 && fn / T < vjoin) vjoin = (float)STEP_TIMER_HZ / ceilf((float)STEP_TIMER_HZ * T / fn);
  // Joined, the move lasts at least two profile ticks: the tick that sees it start prepares the next one in time.
  const float tick_cap = fn * (float)PROFILE_TICK_HZ * 0.5f;
  if (tick_cap < vjoin) vjoin = tick_cap;
  // Alone, from rest to rest: slower when duration_ms asks, solving n/v + v/a = T for the cruise velocity. The
  // stepper's overheads (profile_s) make the motion a little longer than that, so aim earlier by them: it ends by
  // duration_ms.
  float vfast = vc;
  uint8_t stretched = 0;
  if (T > 0 && fn / vc + vc / amax < T) {
    float v = stretch_v(fn, amax, T);
    if (v < vc) {
      vc = v;
      stretched = 1;
    }
  }
  float v0;
  uint32_t ramp_steps;
  float t = shape(fn, n, vc, amax, &v0, &ramp_steps);
  float aim = T;
  for (uint8_t k = 0; stretched && t > T && k < 3; k++) {  // converges in one or two
    aim -= t - T + 0.0005f;
    float v = stretch_v(fn, amax, aim);
    if (v > vfast) break;  // the limits allow no faster profile
    float v0b;
    uint32_t rb;
    float tb = shape(fn, n, v, amax, &v0b, &rb);
    vc = v, v0 = v0b, ramp_steps = rb, t = tb;
  }
  uint8_t never_joins = vjoin < v0;  // too short to run on at even its stop rate
  if (vjoin < v0) vjoin = v0;
  b->v0 = to_fixed(v0);
  b->vc = to_fixed(vjoin);
  b->vc_rest = to_fixed(vc);
  b->stop_sq4 = sq4_of(v0);
  b->vc_sq4 = sq4_of(vjoin);
  b->a8_full = (uint32_t)(8.0f * amax + 0.5f);  // 8 a s < 4 (vc^2 - v0^2) + 8 a on the ramps: fits
  float span = 8.0f * amax * fn;
  b->span_sq4 = span > 4.0e9f ? 0xFFFFFFFFUL : (uint32_t)span;
  float t_ms = t * 1000.0f;
  if (t_ms > (float)duration_ms) b->planned_ms = t_ms > 65535.0f ? 65535 : (uint16_t)(t_ms + 0.999f);
  b->entry_sq4 = b->exit_sq4 = b->stop_sq4;
  if (never_joins)
    b->joins = PLAN_NEVER_JOINS;
  else
    junction(b, prev, vjoin, stretched, amax);
  set_accel(b, a8_at(b, b->stop_sq4));
  b->decel_steps = b->vc_sq4 > b->stop_sq4 ? (b->vc_sq4 - b->stop_sq4) / b->a8 + 1 : 0;
  return RBX1_OK;
}

void plan_gripper(plan_block *b, uint16_t pulse_us, uint16_t dwell_ms) {
  memset(b, 0, sizeof(*b));
  b->kind = BLOCK_GRIPPER;
  b->pulse_us = pulse_us;
  b->duration_ms = dwell_ms;
  b->planned_ms = dwell_ms;
  b->back_sq4 = PLAN_UNPLANNED;
}

// The exit and its ramp, as the stepper reads them (interrupts off for the 8 bytes; the division outside).
static void set_exit(plan_block *b, uint32_t exit_sq4) {
  if (b->kind != BLOCK_MOVE || b->n == 0 || b->exit_sq4 == exit_sq4) return;
  uint32_t steps = b->vc_sq4 > exit_sq4 ? (b->vc_sq4 - exit_sq4) / b->a8 + 1 : 0;
  hal_irq_state s = hal_irq_save();
  b->exit_sq4 = exit_sq4;
  b->decel_steps = steps;
  hal_irq_restore(s);
}

// The passes (firmware/README.md, Look-ahead: Passes), cut short GRBL's way where the result is known not to change.
// The backward pass's exit of every entry (back_sq4) is a function of the exit of the entry after it and of that
// entry's own fixed data: the passes keep the chain, so where a recomputed exit equals the one kept, every earlier
// one is unchanged too and the backward pass stops there. The forward pass starts at that entry: up to it entries,
// a8 and exits are those of the previous pass (the same entry of the oldest, the same backward exits). Both stops
// are exact: the plan is the one the full passes make (Lookahead.EarlyStopsPlanAsTheFullPasses compares them).
// Out of line (one call per commit) so that rbx1-avrsim's trace can time it (--time-function: tools/bench/motion).
__attribute__((noinline)) void planner_recalculate(void) {
  plan_block *q[QUEUE_SIZE];
  uint32_t exit[QUEUE_SIZE];
  uint8_t c = queue_blocks(q);  // oldest first; a pop meanwhile leaves the popped block's data in place
  if (c < 2) return;
  // Backward: the last entry ends at its stop rate; each earlier one exits as fast as the next can enter (within
  // its junction limit and what it can slow down from over its own steps).
  uint8_t k = (uint8_t)(c - 1);
  q[k]->back_sq4 = q[k]->stop_sq4;
  for (; k >= 1; k--) {
    plan_block *b = q[k];
    uint32_t back = q[k - 1]->stop_sq4;
    if (b->joins & PLAN_JOINS) {
      // entry <= exit + n a8(entry), a8 falling with the entry by the bend's share: solved for the entry.
      if (b->bend8 > 0.0f) {
        float e = ((float)b->back_sq4 + (float)b->span_sq4) * b->keep;
        back = e < 4.0e9f ? (uint32_t)e : 0xFFFFFFFFUL;
      } else {
        back = add_sat(b->back_sq4, b->span_sq4);
      }
      if (back > b->max_entry_sq4) back = b->max_entry_sq4;
    }
    if (back == q[k - 1]->back_sq4) break;  // never PLAN_UNPLANNED: at most 4e9 (sq4_of)
    q[k - 1]->back_sq4 = back;
  }
  uint8_t from = k ? (uint8_t)(k - 1) : 0;
  // Forward: no exit faster than the move can reach from its own entry (at a8 of that entry). Computed before
  // anything is written, so the stepper never sees a running move's exit raised and lowered again: exits only rise
  // as moves arrive.
  uint32_t entry = q[from]->entry_sq4;
  for (k = from; k < c; k++) {
    // The oldest keeps the a8 of its entry (it may be running); so does a move whose entry did not change.
    uint32_t a8 = q[k]->a8, span = q[k]->span_sq4;
    if (k && entry != q[k]->entry_sq4) {
      q[k]->entry_sq4 = entry;
      a8 = a8_at(q[k], entry);
    }
    if (a8 != q[k]->a8_full) {
      if (a8 <= 0xFFFFUL && q[k]->n <= 0xFFFFUL) {
        span = a8 * q[k]->n;
      } else {
        float f = (float)a8 * (float)q[k]->n;
        span = f < 4.0e9f ? (uint32_t)f : 0xFFFFFFFFUL;
      }
    }
    uint32_t reach = add_sat(entry, span);
    exit[k] = q[k]->back_sq4 > reach ? reach : q[k]->back_sq4;
    if (k) set_accel(q[k], a8);
    entry = (k + 1 < c && (q[k + 1]->joins & PLAN_JOINS)) ? exit[k] : (k + 1 < c ? q[k + 1]->stop_sq4 : 0);
  }
  for (k = from; k < c; k++) set_exit(q[k], exit[k]);
}

void planner_forget(void) {
  plan_block *q[QUEUE_SIZE];
  uint8_t c = queue_blocks(q);
  for (uint8_t k = 0; k < c; k++) q[k]->back_sq4 = PLAN_UNPLANNED;
}

static uint8_t stale;  // main loop only

void planner_mark_stale(void) { stale = 1; }

void planner_poll(void) {
  if (!stale) return;
  stale = 0;
  planner_recalculate();
}
