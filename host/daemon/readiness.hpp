// readiness.hpp - whether the daemon may run a job: one named state, with its reason as data.
#pragma once
#include <string>

#include "error_codes.hpp"

namespace rbx1::daemon {

enum class Readiness {
  Starting,     // no preparation has ended yet (at start, after clear_fault)
  LinkDown,     // the port is absent or the firmware does not answer
  NotPrepared,  // the firmware refused a step of the preparation (enable, home or declare, a stale fault)
  BoardLimits,  // the config's joint limits exceed the board's: nothing is planned
  Fault,        // the firmware is in FAULT (an e-stop, a limit switch, ...): rbx1 clear-fault
  Held,         // the firmware was reset under this daemon: only the operator's clear_fault goes on
  Ready,        // link up, drivers enabled, positions homed or declared
};

const char* readiness_name(Readiness r);

// The state and, when not ready, why in words (the status's link.error, a refused job's message).
struct NotReady {
  Readiness state = Readiness::Starting;
  std::string message;
};

// The error a job gets while the daemon is in state r: fault for a firmware fault, not_ready otherwise.
ErrorCode job_error(Readiness r);

// The transitions (Machine keeps one under its mutex). A hold outlasts every preparation: only release() ends it.
class ReadyState {
 public:
  const NotReady& why() const { return why_; }
  Readiness state() const { return why_.state; }
  bool ready() const { return why_.state == Readiness::Ready; }
  bool held() const { return why_.state == Readiness::Held; }
  const std::string& reason() const { return why_.message; }  // "" when ready or starting
  // A preparation ended: outcome.state Ready, or the reason it stopped at. Ignored while held.
  void prepared(const NotReady& outcome);
  // The daemon no longer knows where the arm is (why: what showed it): not ready until release().
  void hold(const std::string& why);
  // clear_fault: the operator's word that the arm stands at its home pose; the next preparation decides.
  void release();

 private:
  NotReady why_;
};

}  // namespace rbx1::daemon
