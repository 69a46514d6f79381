// motion.cpp - a job's queue entries over the link: flow control on queue_free (batches streamed with the link's
// window), the loop around the journal (motion_journal.cpp), fault handling and link recovery.
#include "motion.hpp"
#include "motion_journal.hpp"

#include <algorithm>
#include <chrono>
#include <optional>
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
    error = link::failed(link.name(), "STOP", r);
    return r;
  }
  auto deadline = Clock::now() + std::chrono::seconds(10);
  for (;;) {
    if (int r = link.status(st); r < 0) {
      error = link::failed(link.name(), "STATUS while stopping", r);
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

std::string firmware_reset(const rbx1_status_resp* before, const rbx1_status_resp& now) {
  if (before && counters_went_back(*before, now)) return "the firmware's counters went back (reset?)";
  if (now.homed != RBX1_ALL_JOINTS_MASK) return "the firmware lost its joint positions (reset?)";
  return "";
}

// One run(): the loop over the job's entries as named steps. Each step returns false once fail() filled the result.
class Motion::Run {
 public:
  Run(Motion& motion, const std::vector<MotionStep>& steps, const MotionHooks& hooks)
      : motion_(motion), link_(motion.link_), steps_(steps), hooks_(hooks) {}

  MotionResult go() {
    if (!start()) return res_;
    while (!journal_->finished()) {
      if (hooks_.aborted()) {
        fail(hooks_.abort_reason(), "job aborted at step " + std::to_string(done() + 1) + " (" + steps_[done()].name + ")");
        return res_;
      }
      if (!send_ahead() || !poll()) return res_;
      Next next = handle_faults();
      if (next == Next::Failed) return res_;
      if (next == Next::Again) continue;
      if (!check_flushed() || !check_timeout()) return res_;
    }
    res_.ok = true;
    return res_;
  }

 private:
  enum class Next { On, Again, Failed };

  bool fail(std::string code, std::string message) {
    res_.ok = false;
    res_.code = std::move(code);
    res_.message = std::move(message);
    return false;
  }
  bool fail(ErrorCode code, std::string message) { return fail(code_name(code), std::move(message)); }
  bool fail(const JournalError& e) { return fail(e.code, e.message); }
  Next failed(ErrorCode code, std::string message) {
    fail(code, std::move(message));
    return Next::Failed;
  }
  size_t done() const { return journal_->done(); }
  std::string step_name(size_t i) const { return i < steps_.size() ? steps_[i].name : "end"; }

  // Reads the firmware's state; on a link failure waits for it to come back. A firmware whose counters went back
  // or that lost its positions is not the one this run talked to.
  bool read_status() {
    for (;;) {
      int r = link_.status(st_);
      if (r == 0) {
        std::string reset = firmware_reset(have_last_ ? &res_.last : nullptr, st_);
        res_.last = st_;
        have_last_ = true;
        if (hooks_.on_status) hooks_.on_status(st_);
        if (!reset.empty()) return fail(ErrorCode::FirmwareReset, reset + "; refusing to guess the arm's state");
        return true;
      }
      if (!link_error(r)) return fail(ErrorCode::LinkError, link_.name() + ": STATUS failed: " + link::error_text(r));
      if (!recover()) return false;
    }
  }

  // Waits for the link to come back (Motion::recover); a failure ends the run (aborted: by its reason).
  bool recover() {
    if (motion_.recover(hooks_, err_) < 0) return fail(hooks_.aborted() ? hooks_.abort_reason() : code_name(ErrorCode::LinkDown), err_);
    res_.recovered++;
    return true;
  }

  // The first STATUS: no fault, and entries this host did not send (a previous daemon's) stopped and flushed, so
  // that they never run under this job. The journal counts from the state after that.
  bool start() {
    if (!read_status()) return false;
    if (st_.state == RBX1_STATE_FAULT)
      return fail(ErrorCode::Fault, "firmware is in FAULT (" + fault_names(st_.faults).dump() + "); clear_fault first");
    int foreign = 0;
    if (stop_foreign(link_, st_, foreign, err_) < 0) return fail(ErrorCode::LinkError, err_);
    if (foreign || st_.state != RBX1_STATE_IDLE) {
      hooks_.emit("stopped_foreign", {{"entries", foreign}, {"firmware", status_json(st_)}});
      if (st_.state != RBX1_STATE_IDLE)
        return fail(ErrorCode::Fault, "firmware not idle after stopping foreign entries (" +
                                 std::string(state_name(st_.state)) + ")");
      res_.last = st_;
    }
    std::vector<std::string> names;
    for (const MotionStep& s : steps_) names.push_back(s.name);
    journal_.emplace(std::move(names), st_);
    head_since_ = Clock::now();
    return true;
  }

  // Sends batches ahead while the queue has room (never while the firmware stops, homes or holds a fault), then
  // announces the head of the queue.
  bool send_ahead() {
    bool can_send = st_.state == RBX1_STATE_IDLE || st_.state == RBX1_STATE_MOVING;
    while (can_send && journal_->next_batch() > 0) {
      bool more = true;
      if (!send_batch(more)) return false;
      if (!more) break;
    }
    std::vector<JournalEvent> events;
    journal_->announce(events);
    report(events);
    return true;
  }

  // One batch as one stream with the link's window in flight. more: false after a refusal (room or state comes
  // back: poll and retry; a fault latched since the last STATUS is for handle_faults) or an outage.
  bool send_batch(bool& more) {
    std::vector<link::StreamRequest> batch = make_batch(journal_->sent(), journal_->next_batch());
    int r = link_.stream(batch);
    std::vector<JournalEvent> events;
    JournalError error;
    BatchEnd end = journal_->take_answers(batch, events, error);
    report(events);
    if (error) return fail(error);
    more = end != BatchEnd::Refused && r == 0;
    if (end == BatchEnd::Refused || r == 0) return true;
    if (!link_error(r)) return fail(ErrorCode::LinkError, link::failed(link_.name(), "request", r));
    return after_outage();  // then handle_faults() sees a heartbeat loss before more is sent
  }

  std::vector<link::StreamRequest> make_batch(size_t first, size_t count) const {
    std::vector<link::StreamRequest> batch(count);
    for (size_t i = 0; i < count; ++i) {
      const MotionStep& s = steps_[first + i];
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
    return batch;
  }

  // At-most-once after the link failed under a batch: once it is back, the firmware's counters say which of the
  // unanswered entries it queued (the journal resolves them).
  bool after_outage() {
    if (!recover() || !read_status()) return false;
    std::vector<JournalEvent> events;
    JournalError error = journal_->outage(st_, events);
    report(events);
    return error ? fail(error) : true;
  }

  // Waits one poll period, reads STATUS and reconciles the journal with it.
  bool poll() {
    std::this_thread::sleep_for(std::chrono::milliseconds(motion_.options_.poll_ms));
    return read_status() && reconcile();
  }

  bool reconcile() {
    std::vector<JournalEvent> events;
    JournalError error = journal_->reconcile(st_, events);
    report(events);
    return error ? fail(error) : true;
  }

  // An e-stop ends the run; a lost heartbeat (the outage outlived it: the firmware stopped and flushed its queue,
  // the journal moved sent() back to the first entry that did not complete) is cleared and the run goes on
  // (Again); any other fault ends it.
  Next handle_faults() {
    if (st_.state != RBX1_STATE_FAULT && !(st_.faults & RBX1_FAULTS_LATCHING)) return Next::On;
    if (st_.faults & (RBX1_FAULT_ESTOP_INPUT | RBX1_FAULT_ESTOP_COMMAND))
      return failed(ErrorCode::Estop, "e-stop: motion stopped at step " + std::to_string(done() + 1) + " (" +
                                 step_name(done()) + ")");
    if ((st_.faults & RBX1_FAULTS_LATCHING) == RBX1_FAULT_HEARTBEAT_LOST && st_.state != RBX1_STATE_STOPPING) {
      hooks_.emit("heartbeat_lost", {{"completed", done()}, {"flushed", journal_->flushed()}});
      if (motion_.clear_heartbeat_lost(hooks_, st_, res_.recovered, err_) < 0) return failed(ErrorCode::Fault, err_);
      res_.last = st_;
      if (!reconcile()) return Next::Failed;
      res_.resent += int(journal_->resend_flushed());  // their targets are absolute: sending them again resumes
      return Next::Again;
    }
    if (st_.state == RBX1_STATE_FAULT)
      return failed(ErrorCode::Fault, "firmware fault " + fault_names(st_.faults).dump() + " at step " +
                                 std::to_string(done() + 1));
    return Next::On;
  }

  // Entries flushed with no fault: a STOP this job did not send.
  bool check_flushed() {
    if (!journal_->flushed() || st_.state == RBX1_STATE_STOPPING) return true;
    return fail(ErrorCode::Stopped, "the firmware flushed " + std::to_string(journal_->flushed()) + " entries of this job at step " +
                               std::to_string(done() + 1) + " without a fault (a STOP from elsewhere?)");
  }

  // The head of the queue has its planned time plus move_timeout_s to complete.
  bool check_timeout() {
    if (done() >= journal_->sent()) return true;
    double allowed = planned_s(steps_[done()]) + motion_.options_.move_timeout_s;
    if (std::chrono::duration<double>(Clock::now() - head_since_).count() <= allowed) return true;
    return fail(ErrorCode::Timeout, "step " + std::to_string(done() + 1) + " (" + steps_[done()].name +
                               ") did not complete within " + std::to_string(int(allowed)) + " s");
  }

  // The journal's events as the job's events; a completion or a new head restarts the head's clock.
  void report(const std::vector<JournalEvent>& events) {
    for (const JournalEvent& e : events) {
      const MotionStep& s = steps_[e.step];
      switch (e.kind) {
        case JournalEvent::Sent:
          hooks_.emit("sent", step_json(s, e.step));
          if (hooks_.on_sent) hooks_.on_sent(e.step);
          break;
        case JournalEvent::StepDone: {
          nlohmann::json j = step_json(s, e.step);
          j["moves_done"] = st_.moves_done;
          j["position"] = std::vector<int32_t>(st_.position, st_.position + RBX1_JOINTS);
          hooks_.emit("step_done", j);
          head_since_ = Clock::now();
          break;
        }
        case JournalEvent::Step:
          hooks_.emit("step", step_json(s, e.step));
          head_since_ = Clock::now();
          break;
        case JournalEvent::Outage:
          hooks_.emit("journal", {{"step", e.step + 1}, {"name", s.name}, {"accepted_before_outage", e.accepted}});
          break;
      }
    }
  }

  Motion& motion_;
  link::Link& link_;
  const std::vector<MotionStep>& steps_;
  const MotionHooks& hooks_;
  MotionResult res_;
  rbx1_status_resp st_{};
  std::string err_;
  bool have_last_ = false;
  std::optional<MotionJournal> journal_;
  Clock::time_point head_since_;
};

MotionResult Motion::run(const std::vector<MotionStep>& steps, const MotionHooks& hooks) {
  return Run(*this, steps, hooks).go();
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
      error = link::failed(link_.name(), "CLEAR_FAULT", r);
      return r;
    }
    if (r < 0) {
      if (int rr = recover(hooks, error); rr < 0) return rr;
      ++recovered;
    }
    if ((r = link_.status(st)) < 0) {
      if (!link_error(r) || recover(hooks, error) < 0) {
        if (error.empty()) error = link::failed(link_.name(), "STATUS", r);
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
                (r < 0 ? link::error_text(r) : std::string(rbx1_status_name(en.status)));
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
