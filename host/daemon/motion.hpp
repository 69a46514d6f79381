// motion.hpp - runs a list of queue entries (moves, gripper actions) over the link, keeping a journal of what the
// firmware accepted and completed so that a lost link or a vanished port never loses or repeats a move.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "error_codes.hpp"
#include "link.hpp"

namespace rbx1::daemon {

// One firmware queue entry. Moves are absolute step targets, so resending one that never ran is always safe.
struct MotionStep {
  std::string name;  // "approach", "descend", ... (events and logs)
  bool gripper = false;
  std::array<int32_t, RBX1_JOINTS> target{};  // move: absolute steps
  uint16_t duration_ms = 0;                   // move: planned duration (0 = as fast as allowed)
  uint16_t pulse_us = 0, dwell_ms = 0;        // gripper
};

struct MotionOptions {
  int poll_ms = 50;                 // STATUS polling (also keeps the firmware's heartbeat fed)
  double move_timeout_s = 20;       // slack beyond a step's planned time
  double reconnect_timeout_s = 30;  // how long the link may stay away
};

// Outcome of run(): ok, or an error code/message for the reply.
struct MotionResult {
  bool ok = false;
  std::string code, message;  // code: an ErrorCode's wire name, or an abort reason of the job's (jog's client_gone)
  rbx1_status_resp last{};  // the last STATUS read
  int resent = 0;           // steps sent again after a heartbeat-loss stop flushed them
  int recovered = 0;        // link recoveries during the run
  bool failed_with(ErrorCode c) const { return !ok && code == code_name(c); }
};

// Callbacks into the job: events, abort checks, every STATUS read (the daemon's status cache).
struct MotionHooks {
  std::function<void(const std::string& event, nlohmann::json fields)> emit;
  std::function<bool()> aborted;             // true once an e-stop (or shutdown) asked the job to end
  std::function<std::string()> abort_reason; // "estop" ...
  std::function<void(const rbx1_status_resp&)> on_status;
  std::function<void(size_t index)> on_sent; // after the firmware accepted entry index (latency probes)
};

class Motion {
 public:
  Motion(link::Link& link, MotionOptions options) : link_(link), options_(options) {}
  // Executes steps in order, sending ahead while the firmware's queue has room, and returns when all completed
  // (STATUS.moves_done), on a firmware fault, on abort, or when the link stays down.
  MotionResult run(const std::vector<MotionStep>& steps, const MotionHooks& hooks);
  // Waits for the link to come back (reconnect() on the same path) within the configured time. 0 or -errno.
  int recover(const MotionHooks& hooks, std::string& error);

 private:
  class Run;  // one run(): its state and named steps (motion.cpp)
  // CLEAR_FAULT (and ENABLE when needed) after a heartbeat loss, surviving link errors; st is the STATUS after.
  int clear_heartbeat_lost(const MotionHooks& hooks, rbx1_status_resp& st, int& recovered, std::string& error);

  link::Link& link_;
  MotionOptions options_;
};

// Entries in the firmware's queue that this host did not send (a previous daemon's, a power-cycled board's
// leftovers never exist): when the firmware is moving, homing, stopping or its queue is not empty, STOP, and
// wait until it is at rest. st: the last STATUS in, the STATUS at rest out; stopped: entries that were queued.
// 0 or -errno (error filled).
int stop_foreign(link::Link& link, rbx1_status_resp& st, int& stopped, std::string& error);
// True when any of STATUS's queue counters is below the earlier reading (a power-cycled or another firmware).
bool counters_went_back(const rbx1_status_resp& before, const rbx1_status_resp& now);
// The one firmware-reset check (power, watchdog, USB re-plug, another board on the port): why `now` is not the
// firmware this host prepared ("the firmware lost its joint positions (reset?)", "the firmware's counters went
// back (reset?)"), or "" when it may be. before: the previous STATUS of this firmware, null when none.
std::string firmware_reset(const rbx1_status_resp* before, const rbx1_status_resp& now);

// "IDLE", "MOVING", ... for a state byte; fault bits as names.
const char* state_name(uint8_t state);
nlohmann::json fault_names(uint16_t faults);
nlohmann::json status_json(const rbx1_status_resp& s);

}  // namespace rbx1::daemon
