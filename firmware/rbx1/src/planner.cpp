// planner.cpp - coordinated move planning: dominant-joint trapezoid scaled so every joint stays in its limits.
#include "planner.h"

#include <math.h>
#include <string.h>

#include "config.h"
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

uint8_t plan_move(plan_block *b, const int32_t start[6], const int32_t target[6], uint16_t duration_ms) {
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
  if (n == 0) return RBX1_OK;  // nothing to step: the entry is a dwell of duration_ms

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
  // Slower when duration_ms asks: solve n/v + v/a = T for the cruise velocity. The stepper's overheads
  // (profile_s) make the motion a little longer than that, so aim earlier by them: it ends by duration_ms.
  float T = (float)duration_ms * 0.001f, vfast = vc;
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
  b->ramp_steps = ramp_steps;
  b->v0sq4 = (uint32_t)(4.0f * v0 * v0 + 0.5f);  // <= 4 vc^2 <= 1.6e9: fits
  b->a8 = (uint32_t)(8.0f * amax + 0.5f);        // 8 a s < 4 (vc^2 - v0^2) + 8 a on the ramps: fits
  b->v0 = to_fixed(v0);
  b->vc = to_fixed(vc);
  float dv = amax * (float)PLAN_V_ONE / (float)PROFILE_TICK_HZ;
  b->dv = dv < 1.0f ? 1 : (dv > 4.0e9f ? 4000000000UL : (uint32_t)dv);
  float t_ms = t * 1000.0f;
  if (t_ms > (float)duration_ms) b->planned_ms = t_ms > 65535.0f ? 65535 : (uint16_t)(t_ms + 0.999f);
  return RBX1_OK;
}

void plan_gripper(plan_block *b, uint16_t pulse_us, uint16_t dwell_ms) {
  memset(b, 0, sizeof(*b));
  b->kind = BLOCK_GRIPPER;
  b->pulse_us = pulse_us;
  b->duration_ms = dwell_ms;
  b->planned_ms = dwell_ms;
}
