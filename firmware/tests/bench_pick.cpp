// bench_pick.cpp - the pick's motion time before and after issue 9, on the firmware core and the simulated board's
// clock (exact, the same run): "before" is the pick as one joint move per phase with the arm stopping between
// moves (a zero-length MOVE between two moves is a stop: the look-ahead never runs on across it); "after" is the
// pick with straight lines (host/arm/line.cpp) streamed to the look-ahead. Same firmware limits (defaults), same
// joint speed (arm defaults; and both again at 90 deg/s), same object. Prints one JSON object (tools/bench/motion reads it), with each phase's
// time in both (from the previous entry's completion to the phase's last entry's completion).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "firmware.h"
#include "hal_sim.hpp"
#include "joint_steps.hpp"
#include "pick.hpp"
#include "rbx1_proto.h"
#include "vision_map.hpp"

namespace {

using namespace rbx1;

struct Host {
  rbx1_decoder dec{};
  std::vector<std::vector<uint8_t>> replies;
  uint8_t seq = 0;
  std::vector<uint64_t> done;  // simulated tick of every completed entry

  Host() {
    rbx1_decoder_init(&dec, &Host::on_frame, &Host::on_reject, this);
    sim::board().on_entry_done = [this](uint8_t, uint16_t, const int32_t*, const int32_t*, const int32_t*, uint16_t,
                                        uint16_t) { done.push_back(sim::board().now); };
  }
  static void on_frame(void* ctx, const rbx1_frame* f) {
    static_cast<Host*>(ctx)->replies.emplace_back(f->payload, f->payload + f->len);
  }
  static void on_reject(void*, uint8_t, uint8_t, uint8_t) {}

  void tick() {  // a quarter of a millisecond of the board, the main loop once
    sim::run_until(sim::board().now + sim::kTicksPerMs / 4);
    fw_loop();
    auto& tx = sim::board().tx;
    if (!tx.empty()) rbx1_decoder_feed(&dec, tx.data(), tx.size());
    tx.clear();
  }
  // One request; returns the reply's first byte (the status).
  uint8_t request(uint8_t type, const uint8_t* p, uint8_t len) {
    uint8_t f[RBX1_MAX_FRAME];
    size_t n = rbx1_frame_encode(f, sizeof f, seq++, type, p, len);
    replies.clear();
    sim::board().rx.insert(sim::board().rx.end(), f, f + n);
    for (int i = 0; i < 400 && replies.empty(); i++) tick();
    return replies.empty() || replies[0].empty() ? 0xFF : replies[0][0];
  }
  uint8_t move(const arm::Steps& t, uint16_t ms) {
    rbx1_move_req q{};
    for (int j = 0; j < RBX1_JOINTS; j++) q.target[j] = t[j];
    q.duration_ms = ms;
    uint8_t p[RBX1_MOVE_REQ_LEN];
    return request(RBX1_MSG_MOVE, p, rbx1_move_req_pack(&q, p));
  }
  uint8_t gripper(uint16_t us, uint16_t dwell) {
    rbx1_gripper_req q{us, dwell};
    uint8_t p[RBX1_GRIPPER_REQ_LEN];
    return request(RBX1_MSG_GRIPPER, p, rbx1_gripper_req_pack(&q, p));
  }
};

struct Entry {
  bool gripper;
  arm::Steps target;
  uint16_t ms, pulse;
  std::string phase;  // empty for the zero-length MOVEs that stop the arm between moves
};

// Runs the entries from `start` on a freshly powered board; returns the seconds from the first MOVE sent to the
// last entry's completion, or -1. `phases` gets "name": seconds for each phase, in order.
double run(const std::vector<Entry>& entries, const arm::Steps& start, std::string& phases) {
  sim::board() = sim::Board{};
  sim::erase_eeprom();
  sim::power_on();
  fw_setup();
  Host h;
  uint8_t on = 1, p[RBX1_SET_POSITION_REQ_LEN];
  if (h.request(RBX1_MSG_ENABLE, &on, 1) != RBX1_OK) return -1;
  rbx1_set_position_req sp{};
  for (int j = 0; j < RBX1_JOINTS; j++) sp.position[j] = start[j];
  if (h.request(RBX1_MSG_SET_POSITION, p, rbx1_set_position_req_pack(&sp, p)) != RBX1_OK) return -1;
  const uint64_t t0 = sim::board().now;
  for (size_t k = 0; k < entries.size();) {
    const Entry& e = entries[k];
    uint8_t st = e.gripper ? h.gripper(e.pulse, e.ms) : h.move(e.target, e.ms);
    if (st == RBX1_OK) {
      k++;
    } else if (st == RBX1_QUEUE_FULL) {
      h.request(RBX1_MSG_STATUS, nullptr, 0);  // the heartbeat meanwhile
    } else {
      std::fprintf(stderr, "bench_pick: entry %zu refused with status %u\n", k, st);
      return -1;
    }
  }
  while (h.done.size() < entries.size() && sim::board().now - t0 < 600 * sim::kTicksPerSecond)
    h.request(RBX1_MSG_STATUS, nullptr, 0);
  if (h.done.size() != entries.size()) return -1;
  uint64_t begin = t0;
  for (size_t k = 0; k < entries.size(); k++) {
    if (entries[k].phase.empty()) {
      begin = h.done[k];
      continue;
    }
    if (k + 1 < entries.size() && entries[k + 1].phase == entries[k].phase) continue;  // not the phase's last
    char buf[96];
    std::snprintf(buf, sizeof buf, "%s\"%s\": %.3f", phases.empty() ? "" : ", ", entries[k].phase.c_str(),
                  (double)(h.done[k] - begin) / sim::kTicksPerSecond);
    phases += buf;
    begin = h.done[k];
  }
  return (double)(h.done.back() - t0) / sim::kTicksPerSecond;
}

}  // namespace

int main() {
  const arm::ArmConfig c;
  arm::TablePoint t = arm::vision_to_base(c, Eigen::Vector2d(9.0, 6.0), -50);
  const arm::PickObject obj{t.x_mm, t.y_mm, t.yaw_deg, 20.0, 30.0};
  const arm::Steps start = arm::scan_steps(c);
  std::string error;
  std::vector<arm::Waypoint> joint_plan, line_plan;
  if (!arm::plan_pick(c, start, obj, "tray", joint_plan, error, false) ||
      !arm::plan_pick(c, start, obj, "tray", line_plan, error, true)) {
    std::fprintf(stderr, "bench_pick: %s\n", error.c_str());
    return 1;
  }
  auto entries = [](const std::vector<arm::Waypoint>& w, bool stop_between) {
    std::vector<Entry> out;
    for (const auto& x : w) {
      bool g = x.kind == arm::WaypointKind::Gripper;
      if (stop_between && !g && !out.empty() && !out.back().gripper)
        out.push_back(Entry{false, out.back().target, 0, 0, ""});  // a zero-length MOVE: a stop
      out.push_back(Entry{g, x.steps, g ? x.dwell_ms : x.duration_ms, x.pulse_us, x.name});
    }
    return out;
  };
  std::string phases_before, phases_after, phases_stopping;
  const double before = run(entries(joint_plan, true), start, phases_before);
  const double after = run(entries(line_plan, false), start, phases_after);
  const double lines_stopping = run(entries(line_plan, true), start, phases_stopping);
  if (before < 0 || after < 0 || lines_stopping < 0) {
    std::fprintf(stderr, "bench_pick: a run did not complete\n");
    return 1;
  }
  // The same at the tests' fast joint speed (90 deg/s, as rbx1fw_line_tests): the lines run at the joints'
  // limits there, not at a joint move's pace.
  arm::ArmConfig fast = c;
  fast.speeds.joint_speed_deg_s = 90.0;
  std::vector<arm::Waypoint> joint_fast, line_fast;
  if (!arm::plan_pick(fast, start, obj, "tray", joint_fast, error, false) ||
      !arm::plan_pick(fast, start, obj, "tray", line_fast, error, true)) {
    std::fprintf(stderr, "bench_pick: %s\n", error.c_str());
    return 1;
  }
  std::string phases_before_fast, phases_after_fast;
  const double before_fast = run(entries(joint_fast, true), start, phases_before_fast);
  const double after_fast = run(entries(line_fast, false), start, phases_after_fast);
  if (before_fast < 0 || after_fast < 0) {
    std::fprintf(stderr, "bench_pick: a run did not complete\n");
    return 1;
  }
  size_t moves_before = 0, moves_after = 0;
  for (const auto& x : joint_plan) moves_before += x.kind == arm::WaypointKind::Move;
  for (const auto& x : line_plan) moves_after += x.kind == arm::WaypointKind::Move;
  std::printf("{\"pick_before_s\": %.3f, \"pick_after_s\": %.3f, \"pick_lines_stopping_s\": %.3f, "
              "\"after_over_before\": %.4f, \"moves_before\": %zu, \"moves_after\": %zu, \"gripper_dwell_s\": %.3f, "
              "\"phases_before_s\": {%s}, \"phases_after_s\": {%s}, \"pick_before_fast_s\": %.3f, "
              "\"pick_after_fast_s\": %.3f, \"phases_after_fast_s\": {%s}}\n",
              before, after, lines_stopping, after / before, moves_before, moves_after, 3 * c.gripper.dwell_ms / 1000.0,
              phases_before.c_str(), phases_after.c_str(), before_fast, after_fast, phases_after_fast.c_str());
  return 0;
}
