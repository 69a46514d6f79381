// test_lookahead.cpp - the look-ahead on the simulated firmware: a stream of 500 short moves (a circle of two joints)
// runs without stopping between them, ends exactly at the last target, keeps every joint within its MAX_SPEED and
// ACCEL (measured from the step timestamps) and each move within its duration_ms; a corner slows to the junction
// speed of the rule (firmware/README.md, Look-ahead), a reversal stops; STOP mid-stream stops within ACCEL; the
// passes cut short plan exactly as the full passes.
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "config.h"
#include "fw_fixture.hpp"
#include "planner.h"
#include "queue.h"
#include "step_trace.hpp"
#include "system.h"

namespace rbx1::fwtest {
namespace {

using Target = std::array<int32_t, RBX1_JOINTS>;

// n moves along 1.1 turns of a circle of radius r steps in J1/J2 from 0 (tools/avrsim/stream.py streams the same
// shape, with longer moves, to the real ELF).
std::vector<Target> circle(int n, double r) {
  std::vector<Target> out;
  for (int k = 1; k <= n; k++) {
    double a = 2 * M_PI * 1.1 * k / n;
    out.push_back({(int32_t)std::lround(r * std::cos(a) - r), (int32_t)std::lround(r * std::sin(a)), 0, 0, 0, 0});
  }
  return out;
}

// The junction rule, independently of planner.cpp: the largest dominant rate at the junction of moves a -> b, c.
double junction_speed(const Target& a, const Target& b, const Target& c, const double vmax[RBX1_JOINTS],
                      const double acc[RBX1_JOINTS]) {
  double da[RBX1_JOINTS], db[RBX1_JOINTS], na = 0, nb = 0;
  for (int i = 0; i < RBX1_JOINTS; i++) {
    da[i] = b[i] - a[i];
    db[i] = c[i] - b[i];
    na = std::max(na, std::fabs(da[i]));
    nb = std::max(nb, std::fabs(db[i]));
  }
  double v = 1e30;
  for (int i = 0; i < RBX1_JOINTS; i++) {
    if (da[i]) v = std::min(v, vmax[i] * na / std::fabs(da[i]));
    if (db[i]) v = std::min(v, vmax[i] * nb / std::fabs(db[i]));
  }
  for (int i = 0; i < RBX1_JOINTS; i++) {
    double d = std::fabs(da[i] / na - db[i] / nb);
    if (d > 0) v = std::min({v, std::sqrt(2 * acc[i] * JUNCTION_LAG_STEPS) / d, std::sqrt(acc[i] * std::min(na, nb) / d)});
  }
  return v;
}

// Sends every target as soon as the queue has room (QUEUE_FULL: let time run), then runs to the end.
void stream(Fw& fw, const std::vector<Target>& targets, uint16_t duration_ms) {
  for (size_t k = 0; k < targets.size();) {
    uint8_t st = fw.move(std::vector<int32_t>(targets[k].begin(), targets[k].end()), duration_ms);
    if (st == RBX1_OK)
      k++;
    else if (st == RBX1_QUEUE_FULL)
      fw.run_ms(1);
    else
      FAIL() << "MOVE " << k << ": status " << (int)st;
  }
  fw.run_until_idle();
}

class Lookahead : public Fw {
 protected:
  void SetUp() override {
    Fw::SetUp();
    ready();
    for (int j = 0; j < RBX1_JOINTS; j++) {
      vmax_[j] = j < 2 ? 2000 : 4000;
      acc_[j] = j < 2 ? 20000 : 8000;
      ASSERT_EQ(config_set((uint8_t)j, RBX1_KEY_MAX_SPEED, (int32_t)vmax_[j]), RBX1_OK);
      ASSERT_EQ(config_set((uint8_t)j, RBX1_KEY_ACCEL, (int32_t)acc_[j]), RBX1_OK);
    }
    tr_.attach();
  }
  double vmax_[RBX1_JOINTS], acc_[RBX1_JOINTS];
  Trace tr_;
};

// 500 moves of 14..22 dominant steps (about 10 ms each): no stop between them, exact, within the limits.
TEST_F(Lookahead, CircleOfFiveHundredMovesRunsWithoutStopping) {
  const std::vector<Target> c = circle(500, 1592);
  stream(*this, c, 0);
  rbx1_status_resp s = status();
  ASSERT_EQ(s.moves_done, 500);
  for (int j = 0; j < RBX1_JOINTS; j++) {
    EXPECT_EQ(s.position[j], c.back()[j]) << "J" << j + 1;
    EXPECT_EQ(sim::board().net[j], c.back()[j]) << "J" << j + 1 << ": pulses on the pins";
  }
  ASSERT_EQ(tr_.done.size(), 500u);
  // Slowest junction of the rule (the rounding of the targets to steps makes some corners sharper).
  double vj = 1e30;
  Target prev{};
  for (size_t k = 0; k + 1 < c.size(); k++) {
    vj = std::min(vj, junction_speed(prev, c[k], c[k + 1], vmax_, acc_));
    prev = c[k];
  }
  const double v0 = std::sqrt(acc_[0] / 2);  // the stop rate of a move led by J1 or J2
  ASSERT_GT(vj, 2 * v0) << "the circle's junctions allow running on";
  // From the 20th move's end to the 480th's (past the ramps), no gap between pulses longer than the slowest
  // junction's step interval (+25% for the 1 ms ramp ticks); over the whole stream none longer than the stop rate's
  // (a stop between two moves would take that interval, a tick and that interval again).
  std::vector<uint64_t> all = tr_.all();
  double mid_gap = 0, gap = 0;
  for (size_t k = 1; k < all.size(); k++) {
    double g = (double)(all[k] - all[k - 1]) / kHz;
    gap = std::max(gap, g);
    if (all[k - 1] >= tr_.done[19] && all[k] <= tr_.done[479]) mid_gap = std::max(mid_gap, g);
  }
  EXPECT_LE(mid_gap, 1.25 / vj) << "junction speed " << vj;
  EXPECT_LE(gap, 1.02 / v0);
  // Every move completed within its share: the stream takes about its length at the nominal speed.
  double took = (double)(all.back() - all.front()) / kHz, length = 0;
  prev = Target{};
  for (const Target& t : c) {
    length += std::max(std::abs(t[0] - prev[0]), std::abs(t[1] - prev[1]));
    prev = t;
  }
  EXPECT_LE(took, length / vj + 0.2) << "ramps at both ends: 2 * vmax / acc = 0.2 s";
  Measured m = measure(tr_, all.front(), all.back());
  expect_within_limits(m, vmax_, acc_);
  std::printf("circle: %zu moves, %.3f s, junction speed >= %.0f steps/s, largest gap %.3f ms mid-stream; J1 %.0f "
              "steps/s %.0f steps/s^2, J2 %.0f steps/s %.0f steps/s^2\n",
              c.size(), took, vj, mid_gap * 1e3, m.max_speed[0], m.max_accel[0], m.max_speed[1], m.max_accel[1]);
}

// duration_ms stays a minimum time when moves run on: each of 100 moves of 20 steps at 15 ms (1333 steps/s).
TEST_F(Lookahead, JoinedMovesKeepTheirDuration) {
  std::vector<Target> line;
  for (int k = 1; k <= 100; k++) line.push_back({20 * k, 7 * k, 0, 0, 0, 0});
  stream(*this, line, 15);
  ASSERT_EQ(tr_.done.size(), 100u);
  EXPECT_EQ(status().position[0], 2000);
  for (size_t k = 1; k < tr_.done.size(); k++) {
    double ms = (double)(tr_.done[k] - tr_.done[k - 1]) / (kHz / 1000);
    EXPECT_GE(ms, 15 - 1) << "move " << k << " (completions are seen on 1 ms ticks)";
  }
  // From the 5th move's end (the first, stretched by duration_ms and alone in the queue when it started, stops; the
  // ramps from and to rest take 44 steps each) to the 96th's, no gap longer than the nominal interval (+25%).
  std::vector<uint64_t> t = tr_.steps[0].empty() ? std::vector<uint64_t>{} : tr_.all();
  double gap = 0;
  for (size_t k = 1; k < t.size(); k++)
    if (t[k - 1] >= tr_.done[4] && t[k] <= tr_.done[95]) gap = std::max(gap, (double)(t[k] - t[k - 1]) / kHz);
  EXPECT_LE(gap, 1.25 * 0.015 / 20);
  EXPECT_GE((double)(t.back() - t.front()) / kHz, 99 * 0.015);
}

// A long move that duration_ms stretched, after a stream that enters it at a corner (the junction would slow it
// below its cruise n / duration_ms): it starts from rest with its ramps inside and ends within duration_ms of the
// stream's end, as a joint move alone; joined at the corner its ramp would fall outside duration_ms.
TEST_F(Lookahead, StretchedMoveAfterACornerKeepsItsDuration) {
  std::vector<Target> path;
  for (int k = 1; k <= 10; k++) path.push_back({100 * k, 0, 0, 0, 0, 0});
  path.push_back({1000 + 600, 1500, 0, 0, 0, 0});  // J2 leads: 1500 steps in 1000 ms, far below MAX_SPEED
  std::vector<uint16_t> ms(path.size(), 60);
  ms.back() = 1000;
  for (size_t k = 0; k < path.size();) {
    uint8_t st = move(std::vector<int32_t>(path[k].begin(), path[k].end()), ms[k]);
    if (st == RBX1_OK)
      k++;
    else
      run_ms(1);
  }
  run_until_idle();
  ASSERT_EQ(tr_.done.size(), path.size());
  EXPECT_EQ(status().position[1], 1500);
  double last = (double)(tr_.done[10] - tr_.done[9]) / (kHz / 1000);
  EXPECT_GE(last, 1000 - 1);
  EXPECT_LE(last, 1000 + 10) << "the stretched move's ramps fell outside its duration_ms";
  Measured m = measure(tr_, tr_.all().front(), tr_.all().back());
  expect_within_limits(m, vmax_, acc_);
}

// A 30 degree corner slows to the junction speed of the rule (J2's jump, the lag bound), not to a stop; a reversal
// stops.
TEST_F(Lookahead, CornerSlowsToTheRuleAndReversalStops) {
  const std::vector<Target> path = {Target{3000, 0, 0, 0, 0, 0}, Target{6000, 1732, 0, 0, 0, 0},
                                    Target{3000, 0, 0, 0, 0, 0}};
  stream(*this, path, 0);
  ASSERT_EQ(tr_.done.size(), 3u);
  const double vj = junction_speed(Target{}, path[0], path[1], vmax_, acc_);
  const double v0 = std::sqrt(acc_[0] / 2);
  // The slowest rate around the corner (1/interval of the union of J1 and J2 within 50 ms of it) and at the
  // reversal.
  auto slowest_near = [&](uint64_t t) {
    std::vector<uint64_t> all = tr_.all();
    double worst = 1e30;
    for (size_t k = 1; k < all.size(); k++)
      if (all[k] + 100000 > t && all[k - 1] < t + 100000)
        worst = std::min(worst, kHz / (double)(all[k] - all[k - 1]));
    return worst;
  };
  EXPECT_GT(vj, 1.5 * v0);
  EXPECT_LT(vj, 0.5 * vmax_[0]);  // the corner slows the move
  EXPECT_NEAR(slowest_near(tr_.steps[0][2999].first), vj, 0.1 * vj) << "corner: junction speed " << vj;
  EXPECT_LT(slowest_near(tr_.steps[0][5999].first), 1.02 * v0) << "reversal: at the stop rate";
  for (int j = 0; j < RBX1_JOINTS; j++) EXPECT_EQ(status().position[j], path.back()[j]);
  Measured m = measure(tr_, tr_.all().front(), tr_.all().back());
  expect_within_limits(m, vmax_, acc_);
}

// STOP while the circle streams at speed: it decelerates within ACCEL through the moves it needs, drops the rest,
// and the counters balance (accepted = done + flushed).
TEST_F(Lookahead, StopMidStreamDeceleratesWithinTheLimits) {
  const std::vector<Target> c = circle(500, 1592);
  size_t k = 0;
  uint64_t t_start = sim::board().now;
  while (sim::board().now - t_start < (uint64_t)(0.5 * kHz)) {  // half a second into the stream
    uint8_t st = move(std::vector<int32_t>(c[k].begin(), c[k].end()), 0);
    if (st == RBX1_OK)
      k++;
    else
      run_ms(1);
  }
  ASSERT_EQ(simple(RBX1_MSG_STOP), RBX1_OK);
  uint64_t t_stop = sim::board().now;
  run_until_idle();
  rbx1_status_resp s = status();
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.moves_accepted, (uint16_t)(s.moves_done + s.moves_flushed));
  EXPECT_EQ(s.queue_free, 16);
  for (int j = 0; j < RBX1_JOINTS; j++) EXPECT_EQ(s.position[j], sim::board().net[j]);
  std::vector<uint64_t> all = tr_.all();
  ASSERT_GT(all.back(), t_stop) << "it decelerated, not stopped dead";
  EXPECT_LT((double)(all.back() - t_stop) / kHz, 2 * vmax_[0] / acc_[0] + 0.01);
  Measured m = measure(tr_, all.front(), all.back());
  expect_within_limits(m, vmax_, acc_);
}

// One request of a random stream: a MOVE (target, duration_ms), a GRIPPER entry or a STOP.
struct Item {
  enum Kind { kMove, kGripper, kStop } kind = kMove;
  Target target{};
  uint16_t duration_ms = 0;
};

// A random walk of all six joints: mostly gentle bends of 3..150 dominant steps (the bend share rules), some sharp
// corners and reversals (the moves stop there), very short moves (never join), zero-length moves, moves stretched by
// duration_ms, gripper entries, and one STOP two thirds in.
std::vector<Item> random_stream(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(0, 1), g(-1, 1);
  std::vector<Item> out;
  std::array<double, RBX1_JOINTS> dir{1, 0.5, 0, 0, 0, 0}, pos{};
  for (int k = 0; k < n; k++) {
    Item it;
    double r = u(rng);
    if (k == 2 * n / 3) {
      it.kind = Item::kStop;
      out.push_back(it);
      continue;
    }
    if (r < 0.03) {
      it.kind = Item::kGripper;
      out.push_back(it);
      continue;
    }
    if (r < 0.10) {
      for (double& d : dir) d = u(rng) < 0.5 ? 0 : g(rng);  // a corner, some joints standing
    } else if (r < 0.14) {
      for (double& d : dir) d = -d;  // a reversal
    } else {
      for (double& d : dir) d += 0.08 * g(rng);  // a bend
    }
    double m = 0;
    for (double d : dir) m = std::max(m, std::fabs(d));
    if (m == 0) dir[0] = m = 1;
    double len = u(rng) < 0.03 ? 0 : u(rng) < 0.08 ? 1 + 2 * u(rng) : 3 + 147 * u(rng);
    for (int j = 0; j < RBX1_JOINTS; j++) {
      pos[j] = std::clamp(pos[j] + len * dir[j] / m, -90000.0, 90000.0);
      it.target[j] = (int32_t)std::lround(pos[j]);
    }
    if (u(rng) < 0.1) it.duration_ms = (uint16_t)(5 + 75 * u(rng));
    out.push_back(it);
  }
  return out;
}

// The passes cut short (planner.cpp: the backward pass stops where the exit it keeps comes out unchanged, the
// forward pass starts there) plan exactly as the full passes: a random stream runs twice from power-up, once with
// planner_forget() before every main-loop iteration (each pass then runs over the whole queue, as before the cut),
// and after every iteration every queued entry's entry, exit, a8, dv and ramp steps, and every step pulse and
// completion time, are the same in both runs.
TEST_F(Lookahead, EarlyStopsPlanAsTheFullPasses) {
  std::mt19937 rng(9);
  const std::vector<Item> items = random_stream(rng, 400);
  struct Run {
    // Every main-loop iteration whose plan differs from the one before: its number, the entry count, then six
    // words per entry.
    std::vector<uint32_t> plans;
    std::vector<uint64_t> pulses, done;
    uint32_t iterations = 0;
    int moves = 0, bends = 0, joined = 0;  // entries joined and with a bend share, over the changed plans
  };
  auto run = [&](bool full) {
    Run out;
    tr_ = Trace{};
    seq_ = 0;
    SetUp();
    EXPECT_EQ(config_set(0xFF, RBX1_KEY_HEARTBEAT_MS, 60000), RBX1_OK);  // the drain after STOP sends nothing
    std::vector<uint32_t> last;  // the previous iteration's snapshot: only changes are kept (exact, and small)
    auto tick = [&] {
      sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
      if (full) planner_forget();
      fw_loop();
      collect();
      plan_block* q[QUEUE_SIZE];
      uint8_t c = queue_blocks(q);
      std::vector<uint32_t> now{c};
      for (uint8_t k = 0; k < c; k++) {
        const plan_block* b = q[k];
        now.insert(now.end(), {b->seq, b->entry_sq4, b->exit_sq4, b->a8, b->dv, b->decel_steps});
      }
      if (now != last) {
        out.plans.push_back(out.iterations);
        out.plans.insert(out.plans.end(), now.begin(), now.end());
        for (uint8_t k = 0; k < c; k++) {
          out.joined += (q[k]->joins & PLAN_JOINS) != 0;
          out.bends += q[k]->bend8 > 0.0f;
        }
        last.swap(now);
      }
      out.iterations++;
    };
    auto send = [&](uint8_t type, const uint8_t* p, uint8_t len) {
      frames_.clear();
      std::vector<uint8_t> f = encode(take_seq(), type, p, len);
      send_bytes(f.data(), f.size());
      for (int i = 0; i < 400 && frames_.empty(); i++) tick();
      EXPECT_FALSE(frames_.empty()) << "no answer";
      return frames_.empty() || frames_[0].payload.empty() ? 0xFF : frames_[0].payload[0];
    };
    auto drain = [&] {
      for (int i = 0; i < 400000 && sys_state() != RBX1_STATE_IDLE; i++) tick();
    };
    for (const Item& it : items) {
      if (it.kind == Item::kStop) {
        EXPECT_EQ(send(RBX1_MSG_STOP, nullptr, 0), RBX1_OK);
        drain();
        continue;
      }
      while (queue_free() == 0) tick();
      uint8_t p[RBX1_MOVE_REQ_LEN];
      uint8_t st;
      if (it.kind == Item::kGripper) {
        rbx1_gripper_req r{1500, 20};
        st = send(RBX1_MSG_GRIPPER, p, rbx1_gripper_req_pack(&r, p));
      } else {
        rbx1_move_req r{};
        std::copy(it.target.begin(), it.target.end(), r.target);
        r.duration_ms = it.duration_ms;
        st = send(RBX1_MSG_MOVE, p, rbx1_move_req_pack(&r, p));
        out.moves++;
      }
      EXPECT_EQ(st, RBX1_OK);
    }
    drain();
    out.pulses = tr_.all();
    out.done = tr_.done;
    return out;
  };
  const Run full = run(true), cut = run(false);
  // The stream exercised the look-ahead: moves joined, most with a bend share.
  EXPECT_GT(full.joined, 1000);
  EXPECT_GT(full.bends, 1000);
  EXPECT_EQ(cut.moves, full.moves);
  ASSERT_EQ(cut.plans.size(), full.plans.size());
  size_t i = 0;
  while (i < full.plans.size() && cut.plans[i] == full.plans[i]) i++;
  EXPECT_EQ(i, full.plans.size()) << "plans differ at word " << i << " of " << full.plans.size();
  EXPECT_EQ(cut.done, full.done);
  EXPECT_EQ(cut.pulses, full.pulses);
  EXPECT_GT(full.pulses.size(), 10000u);
  EXPECT_EQ(cut.iterations, full.iterations);
  std::printf("random stream: %d moves, %u main-loop iterations, %zu plan words compared, %zu pulses\n", full.moves,
              full.iterations, full.plans.size(), full.pulses.size());
}

}  // namespace
}  // namespace rbx1::fwtest
