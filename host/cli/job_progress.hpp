// job_progress.hpp - a running job's progress on a terminal: one line redrawn in place (phase, steps done of the
// plan's total, elapsed), counted as the console's progress line counts them (host/console/www/console.js).
#pragma once
#include <chrono>
#include <string>

#include <nlohmann/json.hpp>

namespace rbx1::cli {

// The progress of one job, folded from its reply lines.
class JobProgress {
 public:
  void add(const nlohmann::json& ev);
  // "pick: approach, 12 of 69 steps, 1.2 s"; "" before the first event. The steps only while the plan's are under way.
  std::string line(const std::string& cmd, double elapsed_s) const;

 private:
  std::string phase_;  // the step executing now, a sort's progress phase, or the last event's name
  int total_ = 0;      // the plan's steps ("planned"), 0 when there is none under way
  int done_ = -1;      // the last step_done of the plan, -1 when the step under way is not the plan's
  bool stepping_ = false;  // the last event was a step's (sent, step, step_done)
};

// The line on stdout: drawn after every event and every tick, erased before anything else is printed (the folded
// phases, the result, an error on stderr) and when it goes out of scope. Off when stdout is not a terminal.
class ProgressLine {
 public:
  ProgressLine(bool on, std::string cmd);
  ~ProgressLine() { clear(); }
  bool on() const { return on_; }
  void add(const nlohmann::json& ev);
  void draw();
  void clear();

 private:
  bool on_;
  std::string cmd_;
  JobProgress progress_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  bool shown_ = false;
};

}  // namespace rbx1::cli
