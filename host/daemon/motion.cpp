// motion.cpp - the journal of sent vs completed queue entries, flow control on queue_free (batches streamed with
// the link's window), and link recovery.
#include "motion.hpp"

#include <algorithm>
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
          {"moves_accepted", s.moves_accepted},
          {"moves_flushed", s.moves_flushed},
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

int stop_foreign(link::Link& link, rbx1_status_resp& st, int& stopped, std::string& error) {
  stopped = 0;
  const uint8_t size = link.firmware().queue_size;
  bool busy = st.state == RBX1_STATE_MOVING || st.state == RBX1_STATE_HOMING || st.state == RBX1_STATE_STOPPING ||
              (st.state != RBX1_STATE_FAULT && size && st.queue_free != size);
  if (!busy) return 0;
  stopped = size >= st.queue_free ? size - st.queue_free : 0;
  spdlog::warn("motion: the firmware is {} with {} queue entries this host did not send; stopping them",
               state_name(st.state), stopped);
  rbx1_stop_resp sr{};
  if (int r = link.stop(sr); r < 0) {
    error = link.name() + ": STOP failed (" + std::to_string(r) + ")";
    return r;
  }
  auto deadline = Clock::now() + std::chrono::seconds(10);
  for (;;) {
    if (int r = link.status(st); r < 0) {
      error = link.name() + ": STATUS failed while stopping (" + std::to_string(r) + ")";
      return r;
    }
    if (st.state == RBX1_STATE_IDLE || st.state == RBX1_STATE_FAULT) return 0;
    if (Clock::now() > deadline) {
      error = "the firmware did not come to rest after STOP (state " + std::string(state_name(st.state)) + ")";
      return -ETIMEDOUT;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

bool counters_went_back(const rbx1_status_resp& before, const rbx1_status_resp& now) {
  return int16_t(uint16_t(now.moves_accepted - before.moves_accepted)) < 0 ||
         int16_t(uint16_t(now.moves_done - before.moves_done)) < 0 ||
         int16_t(uint16_t(now.moves_flushed - before.moves_flushed)) < 0;
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
  bool have_last = false;
  // Read the firmware's state; on a link failure wait for it to come back. 0, or -1 after fail() was filled.
  // A firmware whose counters went back or that lost its positions is not the one this run talked to.
  auto read_status = [&]() -> int {
    for (;;) {
      int r = link_.status(st);
      if (r == 0) {
        bool back = have_last && counters_went_back(res.last, st);
        res.last = st;
        have_last = true;
        if (hooks.on_status) hooks.on_status(st);
        if (back || st.homed != 0x3F) {
          fail("firmware_reset", std::string("the firmware ") +
                                     (back ? "counters went back" : "lost its joint positions") +
                                     " (reset?); refusing to guess the arm's state");
          return -1;
        }
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
  // Entries this host did not send (a previous daemon's) never run under this job: stop and flush them.
  int foreign = 0;
  if (stop_foreign(link_, st, foreign, err) < 0) return fail("link_error", err);
  if (foreign || st.state != RBX1_STATE_IDLE) {
    hooks.emit("stopped_foreign", {{"entries", foreign}, {"firmware", status_json(st)}});
    if (st.state != RBX1_STATE_IDLE) return fail("fault", "firmware not idle after stopping foreign entries (" +
                                                              std::string(state_name(st.state)) + ")");
    res.last = st;
  }
  // The journal, from the firmware's own counters: of the entries accepted since this run began (A), D completed
  // and F were flushed; the rest (A - D - F) wait in its queue. Steps complete in order, so steps[0..D) are done
  // and steps[D..D+queued) are queued; a flush (STOP, heartbeat loss) sends the rest again.
  const rbx1_status_resp base = st;
  auto since = [](uint16_t now, uint16_t then) { return size_t(uint16_t(now - then)); };
  const size_t n = steps.size();
  size_t accepted = 0;   // entries this run had accepted (A as the journal knows it)
  size_t sent = 0;       // next step to send
  size_t done = 0;       // steps completed
  size_t announced = 0;  // steps whose start was reported
  size_t flushed = 0;     // steps flushed and not yet handled (sent again after a heartbeat loss)
  uint8_t queue_free = st.queue_free;
  Clock::time_point head_since = Clock::now();
  // Reconciles the journal with a fresh STATUS. 0, or -1 after fail().
  auto reconcile = [&]() -> int {
    size_t a = since(st.moves_accepted, base.moves_accepted), d = since(st.moves_done, base.moves_done),
           f = since(st.moves_flushed, base.moves_flushed);
    if (a != accepted || d + f > a || d > n) {
      fail("firmware_reset", "the firmware's counters (accepted " + std::to_string(a) + ", done " + std::to_string(d) +
                                 ", flushed " + std::to_string(f) + " since the job began) disagree with the " +
                                 std::to_string(accepted) + " entries this job sent; refusing to guess the arm's state");
      return -1;
    }
    while (done < d) {
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
    size_t queued = a - d - f;
    if (done + queued < sent) {  // flushed: those steps never ran; the fault checks below decide what follows
      flushed += sent - done - queued;
      sent = done + queued;
      if (announced > sent) announced = sent;
    }
    queue_free = st.queue_free;
    return 0;
  };

  while (done < n) {
    if (hooks.aborted()) return fail(hooks.abort_reason(), "job aborted at step " + std::to_string(done + 1) + " (" + steps[done].name + ")");
    // Send ahead while the queue has room (never while the firmware stops, homes or holds a fault).
    bool can_send = st.state == RBX1_STATE_IDLE || st.state == RBX1_STATE_MOVING;
    while (can_send && sent < n && queue_free > 0) {
      // A batch of at most queue_free entries goes out as one stream with the link's window in flight; with no
      // more entries than the queue has room for, none is refused QUEUE_FULL between accepted ones, so the
      // firmware (which runs requests in SEQ order) accepts a prefix of any batch whose answers were lost.
      const size_t first = sent, count = std::min<size_t>(queue_free, n - sent);
      std::vector<link::StreamRequest> batch(count);
      for (size_t i = 0; i < count; ++i) {
        const MotionStep& s = steps[first + i];
        if (s.gripper) {
          rbx1_gripper_req req{s.pulse_us, s.dwell_ms};
          batch[i].type = RBX1_MSG_GRIPPER;
          batch[i].len = rbx1_gripper_req_pack(&req, batch[i].payload);
        } else {
          rbx1_move_req req{};
          for (int j = 0; j < RBX1_JOINTS; ++j) req.target[j] = s.target[j];
          req.duration_ms = s.duration_ms;
          batch[i].type = RBX1_MSG_MOVE;
          batch[i].len = rbx1_move_req_pack(&req, batch[i].payload);
        }
      }
      int r = link_.stream(batch);
      size_t k = 0;  // answers taken in order
      bool refused = false;
      for (; k < count && batch[k].answered; ++k) {
        const MotionStep& s = steps[sent];
        uint8_t status = batch[k].resp_len >= 1 ? batch[k].resp[0] : uint8_t(RBX1_BAD_LENGTH);
        if (batch[k].resp_len >= 2) queue_free = batch[k].resp[1];
        if (status == RBX1_QUEUE_FULL || status == RBX1_BUSY || status == RBX1_FAULT_ACTIVE) {
          // Room or state comes back (poll and retry), or a fault latched since the last STATUS: the loop below
          // decides (e-stop ends the job, a lost heartbeat is recovered, anything else fails it by name).
          queue_free = 0;
          refused = true;
          break;
        }
        if (status != RBX1_OK)
          return fail("rejected", "firmware refused step " + std::to_string(sent + 1) + " (" + s.name + "): " +
                                      rbx1_status_name(status));
        hooks.emit("sent", step_json(s, sent));
        if (hooks.on_sent) hooks.on_sent(sent);
        ++accepted;
        ++sent;
      }
      if (refused) {
        for (size_t j = k + 1; j < count; ++j)
          if (batch[j].answered && batch[j].resp_len >= 1 && batch[j].resp[0] == RBX1_OK)
            return fail("rejected", "firmware accepted step " + std::to_string(first + j + 1) + " after refusing step " +
                                        std::to_string(first + k + 1) + "; the queue's order is lost");
        break;
      }
      if (r < 0) {
        if (!link_error(r)) return fail("link_error", link_.name() + ": request failed (" + std::to_string(r) + ")");
        if (recover(hooks, err) < 0) return fail(hooks.aborted() ? hooks.abort_reason() : "link_down", err);
        res.recovered++;
        // At-most-once: the firmware's accepted counter says how many of the unanswered entries were queued;
        // it runs them in order, so they are the first ones.
        if (read_status() < 0) return res;
        size_t queued = since(st.moves_accepted, base.moves_accepted);
        size_t ran = queued >= accepted ? queued - accepted : count + 1;
        bool fits = ran <= count - k;
        for (size_t j = k; fits && j < count; ++j)
          if (batch[j].answered && batch[j].resp_len >= 1 && (batch[j].resp[0] == RBX1_OK) != (j < k + ran))
            fits = false;
        if (!fits)
          return fail("firmware_reset", "the firmware's counters (accepted " + std::to_string(queued) +
                                            " since the job began) disagree with the " + std::to_string(accepted) +
                                            " entries this job knows plus " + std::to_string(count - k) +
                                            " unanswered; refusing to guess the arm's state");
        for (size_t j = k; j < count && j <= k + ran; ++j) {
          const MotionStep& s = steps[first + j];
          bool took = j < k + ran;
          spdlog::info("motion: step {} ({}) {} before the link went down", first + j + 1, s.name,
                       took ? "was accepted" : "was not accepted");
          hooks.emit("journal", {{"step", first + j + 1}, {"name", s.name}, {"accepted_before_outage", took}});
          if (!took) break;
          hooks.emit("sent", step_json(s, sent));
          if (hooks.on_sent) hooks.on_sent(sent);
          ++accepted;
          ++sent;
        }
        if (reconcile() < 0) return res;
        break;  // re-evaluate faults (heartbeat loss) below before sending more
      }
    }
    if (announced < sent && announced == done) {
      hooks.emit("step", step_json(steps[announced], announced));
      ++announced;
      head_since = Clock::now();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.poll_ms));
    if (read_status() < 0) return res;
    if (reconcile() < 0) return res;
    if (st.state == RBX1_STATE_FAULT || (st.faults & RBX1_FAULTS_LATCHING)) {
      if (st.faults & (RBX1_FAULT_ESTOP_INPUT | RBX1_FAULT_ESTOP_COMMAND))
        return fail("estop", "e-stop: motion stopped at step " + std::to_string(done + 1) + " (" +
                                 (done < n ? steps[done].name : "end") + ")");
      if ((st.faults & RBX1_FAULTS_LATCHING) == RBX1_FAULT_HEARTBEAT_LOST && st.state != RBX1_STATE_STOPPING) {
        // The outage outlived the firmware's heartbeat: it stopped and flushed its queue (reconcile() moved
        // `sent` back to the first step that did not complete). Clear the fault and carry on.
        hooks.emit("heartbeat_lost", {{"completed", done}, {"flushed", flushed}});
        if (clear_heartbeat_lost(hooks, st, res.recovered, err) < 0) return fail("fault", err);
        res.last = st;
        if (reconcile() < 0) return res;
        res.resent += int(flushed);  // their targets are absolute: sending them again resumes the job
        flushed = 0;
        continue;
      }
      if (st.state == RBX1_STATE_FAULT)
        return fail("fault", "firmware fault " + fault_names(st.faults).dump() + " at step " + std::to_string(done + 1));
    }
    if (flushed && st.state != RBX1_STATE_STOPPING)  // flushed with no fault: a STOP this job did not send
      return fail("stopped", "the firmware flushed " + std::to_string(flushed) + " entries of this job at step " +
                                 std::to_string(done + 1) + " without a fault (a STOP from elsewhere?)");
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

int Motion::clear_heartbeat_lost(const MotionHooks& hooks, rbx1_status_resp& st, int& recovered, std::string& error) {
  // CLEAR_FAULT and ENABLE are safe to repeat: a link error on either is recovered and the state read again.
  for (int attempt = 0; attempt < 3; ++attempt) {
    rbx1_clear_fault_resp cf{};
    int r = link_.clear_fault(cf);
    if (r == 0 && cf.status != RBX1_OK) {
      error = std::string("could not clear HEARTBEAT_LOST: CLEAR_FAULT refused: ") + rbx1_status_name(cf.status);
      return -EPERM;
    }
    if (r < 0 && !link_error(r)) {
      error = link_.name() + ": CLEAR_FAULT failed (" + std::to_string(r) + ")";
      return r;
    }
    if (r < 0) {
      if (int rr = recover(hooks, error); rr < 0) return rr;
      ++recovered;
    }
    if ((r = link_.status(st)) < 0) {
      if (!link_error(r) || recover(hooks, error) < 0) {
        if (error.empty()) error = link_.name() + ": STATUS failed (" + std::to_string(r) + ")";
        return r;
      }
      ++recovered;
      continue;
    }
    if (hooks.on_status) hooks.on_status(st);
    if (st.faults & RBX1_FAULTS_LATCHING) continue;  // the CLEAR_FAULT was lost with the link: again
    if (!st.enabled) {
      rbx1_enable_resp en{};
      r = link_.enable(true, en);
      if (r < 0 && link_error(r)) continue;
      if (r < 0 || en.status != RBX1_OK) {
        error = "could not re-enable the drivers after HEARTBEAT_LOST: " +
                (r < 0 ? std::to_string(r) : std::string(rbx1_status_name(en.status)));
        return -EPERM;
      }
      if (link_.status(st) < 0) continue;
      if (hooks.on_status) hooks.on_status(st);
    }
    return 0;
  }
  error = "could not clear HEARTBEAT_LOST: the link kept failing (" + link_.name() + ")";
  return -EIO;
}

}  // namespace rbx1::daemon
