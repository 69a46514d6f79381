// motion.cpp - the journal of sent vs completed queue entries, flow control on queue_free, and link recovery.
#include "motion.hpp"

#include <chrono>
#include <thread>

#include <spdlog/spdlog.h>

namespace rbx1::daemon {

using Clock = std::chrono::steady_clock;

const char* state_name(uint8_t state) {
  switch (state) {
    case RBX1_STATE_IDLE: return "IDLE";
    case RBX1_STATE_MOVING: return "MOVING";
    case RBX1_STATE_HOMING: return "HOMING";
    case RBX1_STATE_STOPPING: return "STOPPING";
    case RBX1_STATE_FAULT: return "FAULT";
  }
  return "UNKNOWN";
}

nlohmann::json fault_names(uint16_t faults) {
  static const char* const names[] = {"ESTOP_INPUT",    "ESTOP_COMMAND",  "LIMIT_HIT",      "HEARTBEAT_LOST",
                                      "HOMING_FAILED",  "WATCHDOG_RESET", "EEPROM_DEFAULTS"};
  nlohmann::json out = nlohmann::json::array();
  for (int b = 0; b < 16; ++b)
    if (faults & (1u << b)) out.push_back(b < 7 ? names[b] : "BIT" + std::to_string(b));
  return out;
}

nlohmann::json status_json(const rbx1_status_resp& s) {
  return {{"state", state_name(s.state)},
          {"faults", fault_names(s.faults)},
          {"homed", s.homed},
          {"inputs", s.inputs},
          {"enabled", s.enabled != 0},
          {"queue_free", s.queue_free},
          {"moves_done", s.moves_done},
          {"gripper_us", s.gripper_us},
          {"position", std::vector<int32_t>(s.position, s.position + RBX1_JOINTS)}};
}

namespace {
bool link_error(int r) { return r == -ETIMEDOUT || r == -ENODEV || r == -EIO || r == -ENOTCONN || r == -EPIPE; }

nlohmann::json step_json(const MotionStep& s, size_t index) {
  nlohmann::json j{{"step", index + 1}, {"name", s.name}, {"kind", s.gripper ? "gripper" : "move"}};
  if (s.gripper) {
    j["pulse_us"] = s.pulse_us;
    j["dwell_ms"] = s.dwell_ms;
  } else {
    j["target"] = s.target;
    j["duration_ms"] = s.duration_ms;
  }
  return j;
}

double planned_s(const MotionStep& s) { return (s.gripper ? s.dwell_ms : s.duration_ms) / 1000.0; }
}  // namespace

int Motion::recover(const MotionHooks& hooks, std::string& error) {
  hooks.emit("link_down", {{"port", link_.name()}});
  spdlog::warn("motion: link down; waiting up to {} s for {}", options_.reconnect_timeout_s, link_.name());
  auto deadline = Clock::now() + std::chrono::milliseconds(int(options_.reconnect_timeout_s * 1000));
  for (;;) {
    if (hooks.aborted()) {
      error = "aborted while the link was down";
      return -ECANCELED;
    }
    int r = link_.wait_reconnect(200, error);
    if (r == 0) break;
    if (Clock::now() >= deadline) {
      error = link_.name() + ": link did not come back within " + std::to_string(options_.reconnect_timeout_s) +
              " s (" + error + ")";
      return r;
    }
  }
  hooks.emit("link_up", {{"port", link_.name()}, {"last_seq", link_.firmware().last_seq}});
  return 0;
}

MotionResult Motion::run(const std::vector<MotionStep>& steps, const MotionHooks& hooks) {
  MotionResult res;
  auto fail = [&](std::string code, std::string message) {
    res.ok = false;
    res.code = std::move(code);
    res.message = std::move(message);
    return res;
  };
  rbx1_status_resp st{};
  std::string err;
  // Read the firmware's state; on a link failure wait for it to come back. 0, or -1 after fail() was filled.
  auto read_status = [&]() -> int {
    for (;;) {
      int r = link_.status(st);
      if (r == 0) {
        res.last = st;
        if (hooks.on_status) hooks.on_status(st);
        return 0;
      }
      if (!link_error(r)) {
        fail("link_error", link_.name() + ": STATUS failed (" + std::to_string(r) + ")");
        return -1;
      }
      if (recover(hooks, err) < 0) {
        fail(hooks.aborted() ? hooks.abort_reason() : "link_down", err);
        return -1;
      }
      res.recovered++;
    }
  };

  if (read_status() < 0) return res;
  if (st.state == RBX1_STATE_FAULT)
    return fail("fault", "firmware is in FAULT (" + fault_names(st.faults).dump() + "); clear_fault first");
  const uint16_t base = st.moves_done;  // entries complete before this run
  const size_t n = steps.size();
  size_t sent = 0;  // entries the firmware accepted (journal: steps[0..sent) are in its queue or done)
  size_t done = 0;  // entries the firmware completed (moves_done - base)
  size_t announced = 0;  // entries whose start was reported
  uint8_t queue_free = st.queue_free;
  Clock::time_point head_since = Clock::now();

  while (done < n) {
    if (hooks.aborted()) return fail(hooks.abort_reason(), "job aborted at step " + std::to_string(done + 1) + " (" + steps[done].name + ")");
    // Send ahead while the queue has room.
    while (sent < n && queue_free > 0) {
      const MotionStep& s = steps[sent];
      uint8_t seq = link_.next_seq();  // the SEQ this request will carry: tells after a reconnect if it ran
      uint8_t status = 0;
      int r;
      if (s.gripper) {
        rbx1_gripper_req req{s.pulse_us, s.dwell_ms};
        rbx1_gripper_resp resp{};
        r = link_.gripper(req, resp);
        status = resp.status;
        queue_free = resp.queue_free;
      } else {
        rbx1_move_req req{};
        for (int j = 0; j < RBX1_JOINTS; ++j) req.target[j] = s.target[j];
        req.duration_ms = s.duration_ms;
        rbx1_move_resp resp{};
        r = link_.move(req, resp);
        status = resp.status;
        queue_free = resp.queue_free;
      }
      if (r < 0) {
        if (!link_error(r)) return fail("link_error", link_.name() + ": request failed (" + std::to_string(r) + ")");
        if (recover(hooks, err) < 0) return fail(hooks.aborted() ? hooks.abort_reason() : "link_down", err);
        res.recovered++;
        // At-most-once: the firmware's last executed SEQ says whether the lost request ran.
        bool ran = link_.firmware().last_seq == seq;
        spdlog::info("motion: step {} ({}) {} before the link went down", sent + 1, s.name,
                     ran ? "was accepted" : "was not received");
        hooks.emit("journal", {{"step", sent + 1}, {"name", s.name}, {"accepted_before_outage", ran}});
        if (ran) {
          if (hooks.on_sent) hooks.on_sent(sent);
          ++sent;
        }
        if (read_status() < 0) return res;
        queue_free = st.queue_free;
        break;  // re-evaluate faults (heartbeat loss) below before sending more
      }
      if (status == RBX1_QUEUE_FULL) {
        queue_free = 0;
        break;
      }
      if (status == RBX1_FAULT_ACTIVE) {
        // A fault latched since the last STATUS: the loop below decides (e-stop ends the job, a lost
        // heartbeat is recovered, anything else fails it with the fault's name).
        queue_free = 0;
        break;
      }
      if (status != RBX1_OK)
        return fail("rejected", "firmware refused step " + std::to_string(sent + 1) + " (" + s.name + "): " +
                                    rbx1_status_name(status));
      hooks.emit("sent", step_json(s, sent));
      if (hooks.on_sent) hooks.on_sent(sent);
      ++sent;
    }
    if (announced < sent && announced == done) {
      hooks.emit("step", step_json(steps[announced], announced));
      ++announced;
      head_since = Clock::now();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.poll_ms));
    if (read_status() < 0) return res;
    size_t now_done = uint16_t(st.moves_done - base);
    if (st.homed != 0x3F)
      return fail("firmware_reset", "the firmware lost its joint positions during step " + std::to_string(done + 1) +
                                        " (reset?); refusing to guess the arm's state");
    if (now_done > sent) {  // more completions than we sent: the firmware is not the one we started with
      return fail("firmware_reset", "moves_done jumped from " + std::to_string(base) + " to " +
                                        std::to_string(st.moves_done) + "; refusing to guess the arm's state");
    }
    while (done < now_done) {
      nlohmann::json j = step_json(steps[done], done);
      j["moves_done"] = st.moves_done;
      j["position"] = std::vector<int32_t>(st.position, st.position + RBX1_JOINTS);
      hooks.emit("step_done", j);
      ++done;
      if (announced < sent && announced == done) {
        hooks.emit("step", step_json(steps[announced], announced));
        ++announced;
      }
      head_since = Clock::now();
    }
    queue_free = st.queue_free;
    if (st.state == RBX1_STATE_FAULT || (st.faults & RBX1_FAULTS_LATCHING)) {
      if (st.faults & (RBX1_FAULT_ESTOP_INPUT | RBX1_FAULT_ESTOP_COMMAND))
        return fail("estop", "e-stop: motion stopped at step " + std::to_string(done + 1) + " (" +
                                 (done < n ? steps[done].name : "end") + ")");
      if ((st.faults & RBX1_FAULTS_LATCHING) == RBX1_FAULT_HEARTBEAT_LOST && st.state != RBX1_STATE_STOPPING) {
        // The outage outlived the firmware's heartbeat: it stopped and flushed its queue. Entries not
        // completed were not executed; their targets are absolute, so sending them again resumes the job.
        hooks.emit("heartbeat_lost", {{"completed", done}, {"flushed", sent - done}});
        rbx1_clear_fault_resp cf{};
        rbx1_enable_resp en{};
        if (link_.clear_fault(cf) < 0 || cf.status != RBX1_OK)
          return fail("fault", "could not clear HEARTBEAT_LOST: " + std::string(rbx1_status_name(cf.status)));
        if (read_status() < 0) return res;
        if (!st.enabled && (link_.enable(true, en) < 0 || en.status != RBX1_OK))
          return fail("fault", "could not re-enable the drivers after HEARTBEAT_LOST");
        res.resent += int(sent - done);
        sent = done;
        announced = done;
        queue_free = st.queue_free;
        continue;
      }
      if (st.state == RBX1_STATE_FAULT)
        return fail("fault", "firmware fault " + fault_names(st.faults).dump() + " at step " + std::to_string(done + 1));
    }
    if (done < sent) {
      double allowed = planned_s(steps[done]) + options_.move_timeout_s;
      if (std::chrono::duration<double>(Clock::now() - head_since).count() > allowed)
        return fail("timeout", "step " + std::to_string(done + 1) + " (" + steps[done].name + ") did not complete within " +
                                   std::to_string(int(allowed)) + " s");
    }
  }
  res.ok = true;
  return res;
}

}  // namespace rbx1::daemon
