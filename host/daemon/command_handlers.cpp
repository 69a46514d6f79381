// command_handlers.cpp - the daemon's handler of each command of the command table (command_table.cpp), one line
// each, in the table's order: a job's runs on the worker (Machine::run_job), an immediate one's at once.
#include "machine.hpp"

namespace rbx1::daemon {

namespace {
using M = Machine;
using Q = const Request&;
using R = std::shared_ptr<Reply>;

template <typename Handler>
struct Entry {
  Command command;
  Handler run;
};

template <typename Handler, size_t N>
Handler lookup(const Entry<Handler> (&table)[N], Command c) {
  for (const auto& e : table)
    if (e.command == c) return e.run;
  return nullptr;
}
}  // namespace

Machine::JobHandler Machine::job_handler(Command c) {
  static const Entry<JobHandler> kJobs[] = {
      {Command::Scan, [](M& m, Reply& r, Q) { m.job_scan(r); }},
      {Command::Pick, [](M& m, Reply& r, Q q) { m.job_pick(r, q.name, q.place); }},
      {Command::Home, [](M& m, Reply& r, Q) { m.job_home(r); }},
      {Command::ClearFault, [](M& m, Reply& r, Q) { m.job_clear_fault(r); }},
      {Command::Jog, [](M& m, Reply& r, Q q) { m.job_jog(r, q); }},
      {Command::PoseSave, [](M& m, Reply& r, Q) { m.job_pose_save(r); }},
      {Command::PlaceSave, [](M& m, Reply& r, Q q) { m.job_place_save(r, q.name); }},
      {Command::Background, [](M& m, Reply& r, Q q) { m.job_background(r, q.frames); }},
      {Command::Teach, [](M& m, Reply& r, Q q) { m.job_teach(r, q); }},
      {Command::CalibrateWorkspace, [](M& m, Reply& r, Q q) { m.job_calibrate_workspace(r, q); }},
      {Command::Sort, [](M& m, Reply& r, Q q) { m.job_sort(r, q); }},
      {Command::Clear, [](M& m, Reply& r, Q q) { m.job_sort(r, q); }},
  };
  return lookup(kJobs, c);
}

Machine::ImmediateHandler Machine::immediate_handler(Command c) {
  static const Entry<ImmediateHandler> kImmediate[] = {
      {Command::Status, [](M& m, Q, R r) { r->result(m.status_reply()); }},
      {Command::Scene, [](M& m, Q, R r) { r->result(m.scene_reply()); }},
      {Command::Estop, [](M& m, Q, R r) { m.answer_estop(*r); }},
      {Command::Shutdown, [](M& m, Q, R r) { m.answer_shutdown(*r); }},
      {Command::Subscribe, [](M& m, Q q, R r) { m.answer_subscribe(q, std::move(r)); }},
      {Command::RecipeSave, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
      {Command::History, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
      {Command::Pause, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
      {Command::Resume, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
      {Command::Cancel, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
      {Command::Recipes, [](M& m, Q q, R r) { m.handle_jobs_request(q, *r); }},
  };
  return lookup(kImmediate, c);
}

}  // namespace rbx1::daemon
