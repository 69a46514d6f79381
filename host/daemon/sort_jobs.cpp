// sort_jobs.cpp - the cell's jobs: sort (each class to its recipe's place) and clear (everything to one place),
// repeating scan, choose, pick, place until nothing mapped is left; pause, resume, cancel; every pick and job into
// the history; the history and recipe requests.
#include <chrono>
#include <cmath>
#include <set>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "library.hpp"
#include "machine.hpp"
#include "pick_plan.hpp"
#include "recipes.hpp"
#include "scan_json.hpp"
#include "sort_choice.hpp"

namespace rbx1::daemon {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

namespace {
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
double round1(double v) { return std::round(v * 10) / 10; }
}  // namespace

// One sort or clear from its first scan to its summary. Each cycle: a scan at the scan pose (which also judges the
// pick before it: the object still there is a failed attempt; a blind frame is taken again, then pick_unverified,
// as in the pick check), the choice, the pick, straight back to the scan
// pose (no homing between picks). The rescan after each pick is the safe default: a pick may nudge a neighbour.
class SortRun {
 public:
  SortRun(Machine& m, Reply& reply, std::string kind, Recipe recipe, json recipe_label, int max_picks)
      : m_(m), reply_(reply), kind_(std::move(kind)), recipe_(std::move(recipe)), label_(std::move(recipe_label)),
        max_picks_(max_picks), started_(Clock::now()) {}

  void run() {
    // A failure's reply line is written deep in the steps (scan, move); the history rows it leaves go first.
    Reply::FinalHeld final_after_history(reply_);
    std::string error;
    if (m_.history_) job_ = m_.history_->begin_job(kind_, label_, error);
    if (m_.history_ && !job_) spdlog::error("history: {}", error);
    reply_.event("sort_started", {{"job", job_}, {"kind", kind_}, {"recipe", recipe_json(recipe_)}});
    std::string outcome;
    while (outcome.empty()) {
      m_.job_deadline_ns_ = now_ns() + int64_t(m_.config_.daemon.job_timeout_s * 1e9);  // per cycle
      vision::Scan detections;
      if (!scan(detections)) return end_failed();
      if (pending_) judge(detections);
      if (m_.job_control_ == Machine::JobControl::Pause) {
        if (!hold_paused()) return end_failed();
        if (m_.job_control_ == Machine::JobControl::Run) continue;  // resumed: a fresh scan first
      }
      if (m_.job_control_ == Machine::JobControl::Cancel) outcome = "cancelled";
      else if (max_picks_ && attempts_ >= max_picks_) outcome = "max_picks";
      else if (!pick_next(detections, outcome)) return end_failed();
    }
    if (!m_.move_to(reply_, "home", m_.config_.arm.home)) return end_failed();
    json s = summary(outcome);
    if (m_.history_ && job_ && !m_.history_->end_job(job_, outcome, s, error)) spdlog::error("history: {}", error);
    reply_.result(s);
  }

 private:
  struct Pending {  // the pick made, judged by the next scan
    SeenObject object;
    std::string place;
    history::PickRow row;
    Clock::time_point chosen;
  };

  static int64_t now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
  }

  void progress(const std::string& phase) {
    double elapsed = ms_since(started_) / 1000;
    reply_.event("progress", {{"job", job_}, {"phase", phase}, {"picked", picked_total_}, {"attempts", attempts_},
                              {"left", left_}, {"elapsed_s", round1(elapsed)},
                              {"rate_per_min", elapsed > 0 ? round1(picked_total_ * 60 / elapsed) : 0.0}});
  }

  bool scan(vision::Scan& detections) {
    progress("scan");
    auto t = Clock::now();
    if (!m_.move_to(reply_, "scan_pose", m_.config_.arm.scan)) return false;
    // The scan after a pick judges it: blind (nothing where the scan before found several) is taken again, then
    // pick_unverified, as the pick check does; the pick is never counted done on a blind frame.
    if (pending_ ? !m_.judging_scan(reply_, detections, scanned_, pending_->object.cls, pending_->row.attempt)
                 : !m_.capture_and_detect(reply_, detections))
      return false;
    scanned_ = detections.objects.size();
    scan_ms_ = ms_since(t);
    scan_id_.reset();
    if (!m_.history_) return true;
    std::vector<unsigned char> jpeg;
    if (!m_.last_annotated_.empty()) cv::imencode(".jpg", m_.last_annotated_, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
    std::string error;
    if (int64_t id = m_.history_->add_scan(job_, int(detections.objects.size()), jpeg, error)) scan_id_ = id;
    if (!error.empty()) spdlog::warn("history: {}", error);
    return true;
  }

  // The pick before this scan: the object still where it was picked from is a failed attempt.
  void judge(const vision::Scan& detections) {
    Pending p = std::move(*pending_);
    pending_.reset();
    const vision::ScanObject* left = find_same(detections, p.object.cls, p.object.centroid_cm);
    p.row.phases_ms["check"] = round1(scan_ms_);
    p.row.cycle_ms = round1(ms_since(p.chosen));
    if (left) {
      p.row.outcome = "failed";
      p.row.reason = "still_there";
      ++failed_;
      bool retry = p.row.attempt <= m_.config_.daemon.pick_retries;
      p.object.centroid_cm = left->centroid_cm;
      if (retry) tries_.push_back({p.object, p.row.attempt});
      else set_aside_.push_back({p.object, "gave_up", "its pick failed every attempt"});
      reply_.event("pick_failed", {{"name", p.object.cls}, {"attempt", p.row.attempt}, {"reason", "still_there"},
                                   {"centroid_cm", vision::point_json(p.object.centroid_cm)}, {"retry", retry}});
    } else {
      p.row.outcome = "picked";
      ++picked_[p.object.cls][p.place];
      ++picked_total_;
      left_ = std::max(0, left_ - 1);  // until the next choice counts again
      reply_.event("pick_verified", {{"name", p.object.cls}, {"attempt", p.row.attempt}, {"place", p.place},
                                     {"centroid_cm", vision::point_json(p.object.centroid_cm)}, {"cycle_ms", p.row.cycle_ms}});
    }
    write(p.row);
  }

  // The row into the history, then the row as the history gives it back onto the bus (MQTT's pick topic).
  void write(const history::PickRow& row) {
    std::string error;
    if (!m_.history_ || !job_) return;
    int64_t id = m_.history_->add_pick(row, error);
    json written = id ? m_.history_->pick(id, error) : json();
    if (written.is_object()) m_.bus_.publish(Topic::Picks, std::move(written));
    if (!error.empty()) spdlog::error("history: {}", error);
  }

  // Paused: the arm holds at the scan pose, the firmware's heartbeat fed, until resume, cancel or an e-stop.
  bool hold_paused() {
    reply_.event("paused", {{"job", job_}});
    progress("paused");
    while (m_.job_control_ == Machine::JobControl::Pause) {
      if (m_.abort_) {
        std::lock_guard lock(m_.mutex_);
        reply_.error(m_.abort_reason_, "the " + kind_ + " was aborted while paused (" + m_.abort_reason_ + ")");
        return false;
      }
      rbx1_status_resp st{};
      if (m_.link_.status(st) == 0) m_.note_status(st);
      std::this_thread::sleep_for(std::chrono::milliseconds(std::max(20, m_.config_.link.heartbeat_ms)));
    }
    if (m_.job_control_ == Machine::JobControl::Run) reply_.event("resumed", {{"job", job_}});
    return true;
  }

  int attempt_of(const vision::ScanObject& o) const {
    int n = 0;
    for (const auto& [seen, a] : tries_)
      if (same_object(o, seen.cls, seen.centroid_cm)) n = std::max(n, a);
    return n + 1;
  }

  // New skips are reported once per object (an event and a history row); the last scan's skips go to the summary.
  void report_skips(const std::vector<vision::ScanObject>& objects, const std::vector<Skip>& skips) {
    last_skips_ = json::array();
    for (const auto& s : skips) {
      const vision::ScanObject& o = objects[s.index];
      json entry{{"class", s.cls}, {"reason", s.reason}, {"detail", s.detail}, {"centroid_cm", vision::point_json(o.centroid_cm)}};
      last_skips_.push_back(entry);
      bool known = false;
      for (const auto& r : reported_)
        if (same_object(o, r.cls, r.centroid_cm)) known = true;
      if (known) continue;
      reported_.push_back({s.cls, o.centroid_cm});
      entry["index"] = o.index;
      reply_.event("skipped", entry);
      history::PickRow row;
      row.job = job_;
      row.cls = s.cls;
      row.match_score = o.identity.score;
      row.outcome = "skipped";
      row.reason = s.reason + (s.detail.empty() ? "" : ": " + s.detail);
      row.scan = scan_id_;
      write(row);
    }
  }

  // Choose and pick the next object; outcome "done" when nothing mapped is left. false after reply.error.
  bool pick_next(const vision::Scan& detections, std::string& outcome) {
    progress("choose");
    auto chosen_at = Clock::now();
    Sorting s = sort_objects(detections, recipe_, set_aside_);
    left_objects_ = s.left;
    struct Planned {
      std::vector<MotionStep> steps;
      json info;
    };
    std::vector<Planned> plans(detections.objects.size());
    std::vector<Candidate> reachable;
    for (auto& c : s.candidates) {
      std::string error;
      Planned& p = plans[c.index];
      if (!m_.plan_pick(detections, detections.objects[c.index], c.place, p.steps, p.info, error)) {
        s.skips.push_back({c.index, c.cls, "unreachable", error});
        continue;
      }
      // The single pick's plan ends at home; a sort goes from the retreat straight to the next scan.
      if (!p.steps.empty() && p.steps.back().name == "home") {
        p.steps.pop_back();
        p.info["waypoints"].erase(p.info["waypoints"].size() - 1);
      }
      for (const auto& w : p.info["waypoints"]) c.travel_ms += w.value("duration_ms", 0.0);
      reachable.push_back(c);
    }
    report_skips(detections.objects, s.skips);
    left_ = int(reachable.size());
    if (reachable.empty()) {
      outcome = "done";
      return true;
    }
    rank(reachable);
    const Candidate& c = reachable.front();
    const vision::ScanObject& o = detections.objects[c.index];
    bool confirmed = true;
    if (!confirm_from_above(detections, c, confirmed)) return false;
    if (!confirmed) return true;  // set aside: the next scan chooses again
    Planned& plan = plans[c.index];
    double plan_ms = ms_since(chosen_at);
    Pending p{{c.cls, o.centroid_cm}, c.place, {}, chosen_at};
    p.row.job = job_;
    p.row.cls = c.cls;
    p.row.match_score = o.identity.score;
    p.row.grip_opening_cm = o.grip.opening_cm;
    p.row.grip_angle_deg = o.grip.angle_deg;
    p.row.place = c.place;
    p.row.attempt = attempt_of(o);
    p.row.scan = scan_id_;
    reply_.event("chosen", {{"name", c.cls}, {"index", o.index}, {"place", c.place}, {"attempt", p.row.attempt},
                            {"disturbs", c.disturbs}, {"travel_ms", round1(c.travel_ms)}, {"candidates", left_}});
    plan.info["steps"] = plan.steps.size();
    plan.info["attempt"] = p.row.attempt;
    reply_.event("planned", plan.info);
    progress("pick");
    auto moving = Clock::now();
    MotionResult result;
    ++attempts_;
    bool ok = m_.run_steps(reply_, plan.steps, result);
    p.row.phases_ms = {{"scan", round1(scan_ms_)}, {"plan", round1(plan_ms)}, {"move", round1(ms_since(moving))}};
    pending_ = std::move(p);
    if (!ok) {  // the motion failed: the attempt goes into the history as such
      pending_->row.outcome = "failed";
      pending_->row.reason = result.code;
      pending_->row.cycle_ms = round1(ms_since(chosen_at));
      write(pending_->row);
      pending_.reset();
      ++failed_;
    }
    return ok;
  }

  // Seen off the optical axis a part shows its side wall, so a look-alike can pass for a class: each pick is
  // judged from straight above first, as a pick by name is (Machine::look_again). One seen there as something
  // else is set aside for the rest of the job (not_confirmed), never picked as this class. false after
  // reply.error (the look's move or capture failed).
  bool confirm_from_above(const vision::Scan& detections, const Candidate& c, bool& confirmed) {
    confirmed = true;
    if (c.cls == kUnknownClass) return true;  // a recipe's "unknown" place takes whatever is not known
    const vision::ScanObject& o = detections.objects[c.index];
    std::optional<bool> taken;
    if (!m_.look_again(reply_, detections, o, c.cls, taken)) return false;
    if (!taken || *taken) return true;
    confirmed = false;
    set_aside_.push_back({{c.cls, o.centroid_cm}, "not_confirmed", "not \"" + c.cls + "\" seen from straight above"});
    return true;
  }

  // The job failed (reply.error was sent): a pick made but not judged is written as unchecked; the job's outcome
  // is the code of that error (estop, link_down, timeout, pick_unverified, ...).
  void end_failed() {
    if (pending_) {
      pending_->row.outcome = "unchecked";
      pending_->row.cycle_ms = round1(ms_since(pending_->chosen));
      write(pending_->row);
      pending_.reset();
    }
    std::string error;
    const std::string outcome = reply_.error_code().value_or("failed");
    json s = summary(outcome);
    if (m_.history_ && job_ && !m_.history_->end_job(job_, outcome, s, error)) spdlog::error("history: {}", error);
  }

  json summary(const std::string& outcome) const {
    double elapsed = ms_since(started_) / 1000;
    json picked = json::object();
    for (const auto& [cls, places] : picked_)
      for (const auto& [place, n] : places) picked[cls][place] = n;
    json left = json::object();
    for (const auto& [cls, n] : left_objects_) left[cls] = n;
    return {{"job", job_}, {"kind", kind_}, {"recipe", label_}, {"outcome", outcome}, {"picked", picked},
            {"picked_total", picked_total_}, {"attempts", attempts_}, {"failed", failed_}, {"skipped", last_skips_},
            {"left", left}, {"elapsed_s", round1(elapsed)},
            {"picks_per_min", elapsed > 0 ? round1(picked_total_ * 60 / elapsed) : 0.0}};
  }

  Machine& m_;
  Reply& reply_;
  std::string kind_;
  Recipe recipe_;
  json label_;  // the recipe as asked: its name, or the object
  int max_picks_;
  Clock::time_point started_;
  int64_t job_ = 0;
  std::optional<int64_t> scan_id_;
  double scan_ms_ = 0;
  size_t scanned_ = 0;  // objects in the last scan (the one the pick being judged was chosen from)
  std::optional<Pending> pending_;
  std::vector<std::pair<SeenObject, int>> tries_;  // objects with failed attempts and how many
  std::vector<SetAside> set_aside_;  // not to be picked again this job (gave_up, not_confirmed)
  std::vector<SeenObject> reported_;
  std::map<std::string, std::map<std::string, int>> picked_;
  std::map<std::string, int> left_objects_;
  json last_skips_ = json::array();
  int picked_total_ = 0, attempts_ = 0, failed_ = 0, left_ = 0;
};

bool Machine::open_history(std::string& error) {
  history_ = history::History::open(config_.daemon.state_dir, config_.history, error);
  if (!history_) return false;
  if (int n = history_->interrupted_at_open())
    spdlog::warn("history: {} job(s) were running when rbx1d last stopped: marked interrupted", n);
  return true;
}

void Machine::job_sort(Reply& reply, const Request& request) {
  Recipe recipe;
  json label;
  std::string error;
  if (request.command == Command::Clear) {
    recipe = {{kAnyClass, request.place}, {kUnknownClass, request.place}};
    label = {{"place", request.place}};
  } else if (request.recipe.is_string()) {
    label = request.recipe;
    if (!RecipeBook(config_.daemon.state_dir).find(request.recipe.get<std::string>(), recipe, error))
      return reply.error(ErrorCode::UnknownRecipe, error);
  } else {
    label = request.recipe;
    if (!recipe_from_json(request.recipe, recipe, error)) return reply.error(ErrorCode::BadRecipe, error);
  }
  if (!check_recipe_here(recipe, request.command == Command::Clear, error))
    return reply.error(request.command == Command::Clear ? ErrorCode::UnknownPlace : ErrorCode::BadRecipe, error);
  if (!ready(reply)) return;
  job_control_ = JobControl::Run;
  SortRun(*this, reply, command_name(request.command), std::move(recipe), std::move(label), request.max_picks).run();
}

bool Machine::recipe_names(std::set<std::string>& places, std::set<std::string>& classes, bool places_only,
                           std::string& error) {
  {
    std::lock_guard lock(mutex_);
    for (const auto& [name, place] : config_.arm.places) places.insert(name);
  }
  if (places_only) {
    classes = {kAnyClass};
    return true;
  }
  vision::Library lib;
  if (!vision::load_library(config_.vision.library_path, lib, error, /*allow_missing=*/true)) return false;
  for (const auto& e : lib.entries) classes.insert(e.name);
  return true;
}

bool Machine::check_recipe_here(const Recipe& recipe, bool places_only, std::string& error) {
  std::set<std::string> places, classes;
  return recipe_names(places, classes, places_only, error) && check_recipe(recipe, places, classes, error);
}

bool Machine::handle_jobs_request(const Request& request, Reply& reply) {
  switch (request.command) {
    case Command::Pause: case Command::Resume: case Command::Cancel: {
      std::lock_guard lock(mutex_);
      bool sorting = running_ && (running_->command == Command::Sort || running_->command == Command::Clear) &&
                     running_reply_ && !running_reply_->finished();
      if (!sorting) {
        reply.error(ErrorCode::NoJob, "no sort or clear is running");
        return true;
      }
      if (request.command == Command::Resume && job_control_ == JobControl::Cancel) {
        reply.error(ErrorCode::Cancelled, "the job is being cancelled");
        return true;
      }
      job_control_ = request.command == Command::Pause    ? JobControl::Pause
                     : request.command == Command::Resume ? JobControl::Run
                                                          : JobControl::Cancel;
      reply.result({{"job", command_name(running_->command)}, {command_name(request.command), true}});
      return true;
    }
    case Command::History: {
      std::string error;
      history::Query q{request.since, request.job, request.limit ? request.limit : 100};
      json j = history_ ? history_->query(q, error) : json{{"jobs", json::array()}, {"picks", json::array()}};
      if (!error.empty()) {
        reply.error(ErrorCode::HistoryFailed, error);
        return true;
      }
      if (request.format == "csv") j["csv"] = history::History::picks_csv(j["picks"]);
      reply.result(j);
      return true;
    }
    case Command::RecipeSave: {
      Recipe recipe;
      std::string error;
      if (!recipe_from_json(request.recipe, recipe, error) || !check_recipe_here(recipe, false, error)) {
        reply.error(ErrorCode::BadRecipe, error);
        return true;
      }
      if (!RecipeBook(config_.daemon.state_dir).save(request.name, recipe, error)) {
        reply.error(ErrorCode::StateFailed, error);
        return true;
      }
      reply.result({{"saved", request.name}, {"recipe", recipe_json(recipe)}, {"file", RecipeBook(config_.daemon.state_dir).path()}});
      return true;
    }
    case Command::Recipes: {  // the console's chooser and editor
      std::map<std::string, Recipe> book;
      std::set<std::string> places, classes;
      std::string error;
      RecipeBook recipes(config_.daemon.state_dir);
      if (!recipes.load(book, error) || !recipe_names(places, classes, false, error)) {
        reply.error(ErrorCode::StateFailed, error);
        return true;
      }
      json saved = json::object();
      for (const auto& [name, recipe] : book) saved[name] = recipe_json(recipe);
      reply.result({{"recipes", saved}, {"file", recipes.path()}, {"places", places}, {"classes", classes}});
      return true;
    }
    default:
      return false;
  }
}

}  // namespace rbx1::daemon
