// job_progress.cpp - a running job's progress line on a terminal (phase, steps done of total, elapsed).
#include "job_progress.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cstdio>

namespace rbx1::cli {

void JobProgress::add(const nlohmann::json& ev) {
  const std::string e = ev.value("event", "");
  if (e.empty()) return;  // the final line: the caller erases the progress before printing it
  const bool stepwise = e == "sent" || e == "step" || e == "step_done";
  const int step = ev.value("step", 0);
  if (e == "planned") total_ = ev.value("steps", 0), done_ = 0;
  // A move after the plan (the next scan of a sort, say): its steps are not the plan's.
  if (e == "sent" && step == 1 && total_ > 0 && done_ == total_) total_ = 0;
  if (e == "step_done") done_ = total_ > 0 && step <= total_ ? step : -1;
  // The phase is the step executing now ("step"); sent lines run ahead of it, so they name it only as a move starts.
  if (e == "step" || (stepwise && !stepping_)) phase_ = ev.value("name", "?");
  else if (e == "progress") phase_ = ev.value("phase", "?");  // a sort's or clear's
  else if (!stepwise) phase_ = e;
  stepping_ = stepwise;
}

std::string JobProgress::line(const std::string& cmd, double elapsed_s) const {
  if (phase_.empty()) return "";
  std::string steps = total_ > 0 && done_ >= 0 ? ", " + std::to_string(done_) + " of " + std::to_string(total_) + " steps" : "";
  char t[32];
  std::snprintf(t, sizeof t, ", %.1f s", elapsed_s);
  return cmd + ": " + phase_ + steps + t;
}

ProgressLine::ProgressLine(bool on, std::string cmd) : on_(on && isatty(STDOUT_FILENO)), cmd_(std::move(cmd)) {}

void ProgressLine::add(const nlohmann::json& ev) {
  if (!on_) return;
  progress_.add(ev);
  draw();
}

void ProgressLine::draw() {
  if (!on_) return;
  double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::string text = progress_.line(cmd_, t);
  if (text.empty()) return;
  // Wider than the terminal it would wrap, and \r would go back to the start of its last row only.
  winsize ws{};
  if (ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 1 && text.size() >= ws.ws_col) text.resize(ws.ws_col - 1);
  std::printf("\r%s\033[K", text.c_str());  // ESC[K: the rest of a longer line before it
  std::fflush(stdout);
  shown_ = true;
}

void ProgressLine::clear() {
  if (!shown_) return;
  std::fputs("\r\033[K", stdout);
  std::fflush(stdout);
  shown_ = false;
}

}  // namespace rbx1::cli
