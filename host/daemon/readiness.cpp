// readiness.cpp - the readiness state's transitions and names.
#include "readiness.hpp"

namespace rbx1::daemon {

const char* readiness_name(Readiness r) {
  switch (r) {
    case Readiness::Starting: return "starting";
    case Readiness::LinkDown: return "link_down";
    case Readiness::NotPrepared: return "not_prepared";
    case Readiness::BoardLimits: return "board_limits";
    case Readiness::Fault: return "fault";
    case Readiness::Held: return "held";
    case Readiness::Ready: return "ready";
  }
  return "?";
}

ErrorCode job_error(Readiness r) { return r == Readiness::Fault ? ErrorCode::Fault : ErrorCode::NotReady; }

void ReadyState::prepared(const NotReady& outcome) {
  if (held()) return;
  why_ = outcome;
  if (ready()) why_.message.clear();
}

void ReadyState::hold(const std::string& why) {
  why_ = {Readiness::Held, why + ": put the arm at its home pose, then rbx1 clear-fault"};
}

void ReadyState::release() { why_ = {}; }

}  // namespace rbx1::daemon
