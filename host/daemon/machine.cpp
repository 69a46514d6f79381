// machine.cpp - the job runner: link preparation, the paper's pick sequence, status, e-stop, shutdown.
#include "machine.hpp"

#include "command_table.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "draw.hpp"
#include "locked_source.hpp"
#include "scan_json.hpp"

#include "board_limits.hpp"
#include "joint_steps.hpp"
#include "pick_plan.hpp"
#include "scene.hpp"

namespace rbx1::daemon {

using Clock = std::chrono::steady_clock;

namespace {
int64_t mono_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}
}  // namespace

Machine::Machine(Config config, std::unique_ptr<gpio::EdgeSource> estop_source,
                 std::unique_ptr<gpio::EdgeSource> start_source, std::unique_ptr<gpio::OutputLine> status_led)
    : config_(std::move(config)),
      estop_source_(std::move(estop_source)),
      start_source_(std::move(start_source)),
      status_led_(std::move(status_led)) {}

int Machine::start_gpio(std::string& error) {
  const auto& g = config_.gpio;
  if (estop_source_) {
    estop_input_ = std::make_unique<gpio::InputWatcher>("estop", std::move(estop_source_), g.estop.active_low,
                                                        g.estop.debounce_ms);
  } else if (g.estop.configured()) {
    estop_input_ = gpio::open_input("estop", g.estop, error);
    if (!estop_input_) return -ENODEV;
  }
  if (estop_input_) {
    int r = estop_input_->start([this](const gpio::InputEvent& ev) {
      if (ev.active) estop("gpio");  // on the watcher thread: ESTOP goes out from here
    });
    if (r < 0) {
      error = estop_input_->describe() + ": cannot watch the e-stop line: " + std::strerror(-r);
      return r;
    }
    spdlog::info("gpio: e-stop on {}", estop_input_->describe());
  }
  if (!status_led_ && g.status_led.configured()) {
    status_led_ = gpio::open_output("status_led", g.status_led, error);
    if (!status_led_) return -ENODEV;
  }
  set_led(false);
  // The start button: the same watcher (debounce, active-low) as the e-stop; a press (the debounced edge to
  // active) runs the configured pick. load_config insists on [daemon] start_pick when the line is configured.
  if (start_source_) {
    start_input_ = std::make_unique<gpio::InputWatcher>("start_button", std::move(start_source_),
                                                        g.start_button.active_low, g.start_button.debounce_ms);
  } else if (g.start_button.configured()) {
    start_input_ = gpio::open_input("start_button", g.start_button, error);
    if (!start_input_) return -ENODEV;
  }
  if (start_input_) {
    int r = start_input_->start([this](const gpio::InputEvent& ev) {
      if (ev.active) start_pressed();  // on the watcher thread: only queues the job
    });
    if (r < 0) {
      error = start_input_->describe() + ": cannot watch the start button: " + std::strerror(-r);
      return r;
    }
    if (config_.daemon.start_pick.empty())
      spdlog::warn("gpio: start button on {} does nothing: daemon.start_pick is empty", start_input_->describe());
    else
      spdlog::info("gpio: start button on {}: pick {} --place {}", start_input_->describe(),
                   config_.daemon.start_pick, config_.daemon.start_place);
  }
  return 0;
}

void Machine::set_led(bool ready) {
  if (status_led_) status_led_->set(ready);
}

Machine::~Machine() { stop(); }

int Machine::start(std::string& error) {
  // What the operator taught overrides the file's defaults (scan pose, places, workspace map, background, library).
  state_ = std::make_unique<StateDir>(config_.daemon.state_dir);
  if (!state_->apply(config_, error)) return -EINVAL;
  if (!open_history(error)) return -EINVAL;
  {
    calib::WorkspaceCalibration w;
    bool saved = config_.arm.camera.pixel_map && calib::load_workspace(state_->path(kWorkspaceFile), w, error);
    std::lock_guard lock(mutex_);
    calibration_ = calibration_summary(saved ? &w : nullptr);
  }
  auto source = camera::open_source(config_.camera, error);
  if (!source) return -ENOENT;
  camera_ = std::make_unique<camera::LockedSource>(std::move(source));
  vision_ = vision::Vision::create(config_.vision, error);
  if (!vision_) return -EINVAL;
  spdlog::info("camera: {}", camera_->describe());
  if (int r = start_gpio(error); r < 0) return r;
  link_.set_timing(config_.link.timeout_ms, config_.link.retries);
  worker_ = std::thread([this] { worker(); });
  status_thread_ = std::thread([this] { publish_status(); });
  return 0;
}

void Machine::publish_status() {
  constexpr auto kPoll = std::chrono::milliseconds(100);
  // A new position goes out as soon as it is read, but no more often than this (status_poll_ms may be 5 ms).
  constexpr auto kMinGap = std::chrono::milliseconds(20);
  constexpr auto kEvery = std::chrono::milliseconds(BusStreams::kStatusEveryMs);
  nlohmann::json last;
  auto sent = Clock::now();
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    status_news_ = false;
    lock.unlock();
    nlohmann::json now = status_reply();
    // The read time alone is no change: at rest it would put a status on the bus every poll.
    nlohmann::json compared = now;
    if (compared["firmware"].is_object()) compared["firmware"].erase("read_at_ns");
    if (compared != last || Clock::now() - sent >= kEvery) {
      last = std::move(compared);
      sent = Clock::now();
      now["ts"] = iso_now();
      bus_.publish(Topic::Status, std::move(now));
    }
    lock.lock();
    status_cv_.wait_for(lock, kPoll, [this] { return stopping_ || status_news_; });
    if (!stopping_ && Clock::now() - sent < kMinGap)
      status_cv_.wait_until(lock, sent + kMinGap, [this] { return stopping_; });
  }
}

void Machine::stop() {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && !worker_.joinable()) return;
    stopping_ = true;
    abort_reason_ = code_name(ErrorCode::Shutdown);
  }
  abort_ = true;
  cv_.notify_all();
  status_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  if (status_thread_.joinable()) status_thread_.join();
  streams_.stop();
  if (estop_input_) estop_input_->stop();
  if (start_input_) start_input_->stop();
  set_led(false);
  link_.close();
}

// ---- e-stop ---------------------------------------------------------------------------------------------

void Machine::estop(const std::string& source) {
  // The source before the frame, so that a job that sees the firmware's e-stop names it (it said "firmware" when
  // it read the latched state first); estop_mu_ guards nothing else, so it cannot delay the frame.
  {
    std::lock_guard lock(estop_mu_);
    last_estop_ = source;
  }
  // Then the frame: nothing else (no other lock, no log) may delay it.
  rbx1_estop_resp resp{};
  int r = link_.estop(resp);
  set_led(false);  // latched: not ready until clear_fault
  {
    std::lock_guard lock(mutex_);
    abort_reason_ = code_name(ErrorCode::Estop);
    for (auto& job : queue_) job.reply->error(ErrorCode::Estop, "e-stop (" + source + ") before the job started");
    queue_.clear();
  }
  abort_ = true;
  cv_.notify_all();
  if (r < 0)
    spdlog::error("estop ({}): ESTOP not acknowledged ({}); the firmware's own e-stop input is the backstop", source, r);
  else
    spdlog::warn("estop ({}): ESTOP acknowledged, status {}", source, rbx1_status_name(resp.status));
}

std::string Machine::estop_source() {
  std::lock_guard lock(estop_mu_);
  return last_estop_.empty() ? "firmware" : last_estop_;
}

// ---- control requests (server thread) --------------------------------------------------------------------

nlohmann::json Machine::call(Command command, int timeout_ms) {
  Request r;
  r.command = command;
  auto q = submit([this](const Request& req, std::shared_ptr<Reply> reply) { handle(req, std::move(reply)); }, r);
  std::vector<nlohmann::json> events;
  nlohmann::json final;
  if (!q->wait_final(events, final, timeout_ms)) return nullptr;
  return final;
}

void Machine::handle(const Request& request, std::shared_ptr<Reply> reply) {
  const CommandSpec& spec = command_spec(request.command);
  if (spec.access != Access::Read) reply->publish_to(bus_, request_json(request));
  if (spec.mode == Mode::Immediate) {
    if (ImmediateHandler answer = immediate_handler(request.command)) answer(*this, request, std::move(reply));
    else reply->error(ErrorCode::Internal, std::string(spec.name) + " has no handler");
    return;
  }
  std::lock_guard lock(mutex_);
  if (stopping_) {
    reply->error(ErrorCode::ShuttingDown, "rbx1d is shutting down");
    return;
  }
  if (const char* busy = busy_locked()) {
    reply->error(ErrorCode::Busy, std::string("a job is running (") + busy + ")");
    return;
  }
  queue_.push_back({request, reply});
  cv_.notify_all();
}

void Machine::answer_subscribe(const Request& request, std::shared_ptr<Reply> reply) {
  unsigned topics = 0;
  for (const auto& name : request.topics)
    if (Topic t; topic_from_name(name, t)) topics |= unsigned(t);
  streams_.start(topics ? topics : kAllTopics, std::move(reply));
}

void Machine::answer_estop(Reply& reply) {
  bool had_job;
  {
    std::lock_guard lock(mutex_);
    had_job = running_.has_value();
  }
  estop("control");
  reply.event("estop_sent", {{"source", "control"}});
  rbx1_status_resp st{};
  nlohmann::json result{{"estop", true}, {"aborted_job", had_job}};
  if (link_.connected() && link_.status(st) == 0) {
    note_status(st);
    result["firmware"] = status_json(st);
  }
  reply.result(result);
}

void Machine::answer_shutdown(Reply& reply) {
  reply.result({{"shutdown", true}});
  if (on_shutdown_) on_shutdown_();
}

const char* Machine::busy_locked() const {
  // A job whose final line went out is over for the client, even if the worker is still tidying up.
  bool running = running_ && running_reply_ && !running_reply_->finished();
  if (running) return command_name(running_->command);
  if (!queue_.empty()) return command_name(queue_.front().request.command);
  return nullptr;
}

void Machine::start_pressed() {
  const auto& d = config_.daemon;
  if (d.start_pick.empty()) {
    spdlog::warn("start button: pressed, but daemon.start_pick is empty; ignored");
    return;
  }
  Request request;
  request.command = Command::Pick;
  request.name = d.start_pick;
  request.place = d.start_place;
  // No client is attached: the job's events and its final line go to the log.
  auto reply = std::make_shared<Reply>(nullptr, Command::Pick);
  reply->log_to("start button");
  std::lock_guard lock(mutex_);
  if (stopping_) {
    spdlog::warn("start button: pressed while shutting down; ignored");
    return;
  }
  if (const char* busy = busy_locked()) {
    spdlog::warn("start button: pressed while a job is running ({}); ignored", busy);
    return;
  }
  spdlog::info("start button: pick {} --place {}", d.start_pick, d.start_place);
  queue_.push_back({request, reply});
  cv_.notify_all();
}

nlohmann::json Machine::status_reply() {
  std::lock_guard lock(mutex_);
  nlohmann::json j;
  j["job"] = running_ ? nlohmann::json(command_name(running_->command)) : nlohmann::json(nullptr);
  j["ready"] = readiness_.ready() && link_.connected() && !(last_status_ && last_status_->state == RBX1_STATE_FAULT);
  j["link"] = {{"port", config_.link.port}, {"connected", link_.connected()}};
  if (!readiness_.reason().empty()) j["link"]["error"] = readiness_.reason();
  auto stats = link_.stats();
  j["link"]["retransmissions"] = stats.retransmissions;
  j["link"]["reconnects"] = stats.reconnects;
  if (link_.connected()) {
    const auto& fw = link_.firmware();
    j["link"]["firmware"] = std::to_string(fw.fw_major) + "." + std::to_string(fw.fw_minor) + "." + std::to_string(fw.fw_patch);
  }
  j["firmware"] = last_status_ ? status_json(*last_status_) : nlohmann::json(nullptr);
  if (last_status_) j["firmware"]["read_at_ns"] = last_status_read_ns_;
  if (last_status_) {
    arm::Steps steps;
    for (int i = 0; i < RBX1_JOINTS; ++i) steps[i] = last_status_->position[i];
    arm::Joints deg = arm::steps_to_joints(config_.arm, steps);
    nlohmann::json a = nlohmann::json::array();
    for (double d : deg) a.push_back(std::round(d * 100) / 100);
    j["joints_deg"] = a;
  }
  j["camera"] = camera_ ? camera_->describe() : "";
  j["calibration"] = calibration_;
  j["places"] = nlohmann::json::array();
  for (const auto& [name, place] : config_.arm.places) j["places"].push_back(name);  // place_save adds under mutex_
  if (std::lock_guard lock(estop_mu_); !last_estop_.empty()) j["last_estop"] = last_estop_;
  return j;
}

nlohmann::json Machine::scene_reply() {
  arm::ArmConfig arm;
  nlohmann::json detections;
  {
    std::lock_guard lock(mutex_);  // place_save, pose_save and the workspace calibration change them
    arm = config_.arm;
    detections = last_detections_;
  }
  return scene_json(arm, detections);
}

void Machine::note_status(const rbx1_status_resp& s) {
  std::lock_guard lock(mutex_);
  set_last_status(s);
}

void Machine::set_last_status(const rbx1_status_resp& s) {
  last_status_read_ns_ = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::system_clock::now().time_since_epoch()).count();
  bool moved = !last_status_ || !std::equal(s.position, s.position + RBX1_JOINTS, last_status_->position) ||
               s.gripper_us != last_status_->gripper_us;
  last_status_ = s;
  if (moved) {
    status_news_ = true;
    status_cv_.notify_all();
  }
}

// ---- the worker ----------------------------------------------------------------------------------------------

void Machine::hold(const std::string& why) {
  // Under mutex_. The daemon no longer knows where the arm is: nothing moves until the operator says so.
  readiness_.hold(why);
  set_led(false);
  spdlog::error("{}", readiness_.reason());
}

bool Machine::note_same_firmware(const rbx1_status_resp& st) {
  std::string reset = firmware_reset(last_status_ ? &*last_status_ : nullptr, st);
  set_last_status(st);
  if (!session_ || reset.empty()) return true;
  if (!readiness_.held()) hold(reset);
  return false;
}

namespace {
bool not_ready(NotReady& why, Readiness state, std::string message) {
  why = {state, std::move(message)};
  return false;
}

// A STATUS for the preparation; false with why (the link is down) when none came.
bool read_status(link::Link& link, rbx1_status_resp& st, NotReady& why) {
  int r = link.status(st);
  return r == 0 || not_ready(why, Readiness::LinkDown, link::failed(link.name(), "STATUS", r));
}

// A preparation request that failed: the link's words for r < 0, else the firmware's refusal.
std::string refused(const std::string& port, const char* what, int r, uint8_t status) {
  return r < 0 ? link::failed(port, what, r) : std::string(what) + " refused: " + rbx1_status_name(status);
}
}  // namespace

bool Machine::prepare(NotReady& why) {
  rbx1_status_resp st{};
  if (!connect(st, why)) return false;
  {
    // A firmware this daemon had prepared and that since lost its positions or restarted its counters was
    // reset (power, watchdog, another board on the port): declaring the home pose again is the operator's call.
    std::lock_guard lock(mutex_);
    if (!note_same_firmware(st)) return not_ready(why, Readiness::Held, readiness_.reason());
  }
  // Queue entries this daemon did not send (a killed predecessor's) are stopped before anything else.
  int foreign = 0;
  std::string error;
  if (stop_foreign(link_, st, foreign, error) < 0) return not_ready(why, Readiness::NotPrepared, error);
  note_status(st);
  if (!clear_stale_heartbeat(st, why)) return false;
  if (st.state == RBX1_STATE_FAULT)  // still usable for status and clear_fault: not ready, the link kept
    return not_ready(why, Readiness::Fault, "firmware in FAULT " + fault_names(st.faults).dump() + " (rbx1 clear-fault)");
  // Lines are timed at the config's joint limits: above the board's, nothing is planned (not ready, the reason).
  if (!check_board_limits(link_, config_.arm, error)) return not_ready(why, Readiness::BoardLimits, error);
  if (!enable_and_home(st, why)) return false;
  if (!read_status(link_, st, why)) return false;
  note_status(st);
  std::lock_guard lock(mutex_);
  session_ = true;
  return true;
}

bool Machine::connect(rbx1_status_resp& st, NotReady& why) {
  if (!link_.connected()) {
    std::string error;
    int r = link_.name().empty() ? link_.open(config_.link, error) : link_.reconnect(error);
    if (r == -EOPNOTSUPP || (r < 0 && link_.name().empty())) r = link_.open(config_.link, error);
    if (r < 0) return not_ready(why, Readiness::LinkDown, error);
    const auto& fw = link_.firmware();
    spdlog::info("link: {} firmware {}.{}.{}, {} joints, queue {}", link_.name(), fw.fw_major, fw.fw_minor,
                 fw.fw_patch, fw.joints, fw.queue_size);
  }
  if (!read_status(link_, st, why)) return false;
  return true;
}

bool Machine::clear_stale_heartbeat(rbx1_status_resp& st, NotReady& why) {
  // A lost heartbeat is the previous host session's doing; an e-stop is the operator's to clear.
  if ((st.faults & RBX1_FAULTS_LATCHING) != RBX1_FAULT_HEARTBEAT_LOST) return true;
  rbx1_clear_fault_resp cf{};
  if (int r = link_.clear_fault(cf); r < 0 || cf.status != RBX1_OK)
    return not_ready(why, Readiness::NotPrepared, "could not clear a stale HEARTBEAT_LOST: " +
                                                      refused(link_.name(), "CLEAR_FAULT", r, cf.status));
  if (!read_status(link_, st, why)) return false;
  note_status(st);
  spdlog::info("link: cleared a stale HEARTBEAT_LOST");
  return true;
}

bool Machine::enable_and_home(rbx1_status_resp& st, NotReady& why) {
  if (!st.enabled) {
    rbx1_enable_resp en{};
    if (int r = link_.enable(true, en); r < 0 || en.status != RBX1_OK)
      return not_ready(why, Readiness::NotPrepared, refused(link_.name(), "ENABLE", r, en.status));
  }
  if (st.homed == RBX1_ALL_JOINTS_MASK) return true;
  return config_.daemon.home_on_start == "home" ? home_on_switches(st, why) : declare_home(why);
}

bool Machine::home_on_switches(rbx1_status_resp& st, NotReady& why) {
  rbx1_home_resp h{};
  if (int r = link_.home(0, h); r < 0 || h.status != RBX1_OK)
    return not_ready(why, Readiness::NotPrepared, refused(link_.name(), "HOME", r, h.status));
  auto deadline = Clock::now() + std::chrono::seconds(120);
  do {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (int r = link_.status(st); r < 0)
      return not_ready(why, Readiness::LinkDown, "link lost while homing: " + link::error_text(r));
    note_status(st);
    if (st.state == RBX1_STATE_FAULT)
      return not_ready(why, Readiness::NotPrepared, "homing failed " + fault_names(st.faults).dump());
  } while (st.state == RBX1_STATE_HOMING && Clock::now() < deadline);
  if (st.homed != RBX1_ALL_JOINTS_MASK) return not_ready(why, Readiness::NotPrepared, "homing did not complete");
  spdlog::info("link: homed on the switches");
  return true;
}

bool Machine::declare_home(NotReady& why) {
  // The arm is taken to be at its configured home pose (the operator put it there).
  arm::Steps home = arm::joints_to_steps(config_.arm, config_.arm.home);
  rbx1_set_position_resp sp{};
  if (int r = link_.set_position(home.data(), sp); r < 0 || sp.status != RBX1_OK)
    return not_ready(why, Readiness::NotPrepared, refused(link_.name(), "SET_POSITION", r, sp.status));
  spdlog::info("link: positions declared at the home pose");
  return true;
}

bool Machine::try_prepare(NotReady& why) {
  bool ok = prepare(why);
  std::lock_guard lock(mutex_);
  readiness_.prepared(ok ? NotReady{Readiness::Ready, ""} : why);
  why = readiness_.why();  // a hold outlasts any preparation
  return readiness_.ready();
}

void Machine::worker() {
  bool logged_error = false;
  for (;;) {
    std::unique_lock lock(mutex_);
    if (stopping_) break;
    if ((!readiness_.ready() || !link_.connected()) && !readiness_.held()) {
      lock.unlock();
      NotReady why;
      bool ok = try_prepare(why);
      lock.lock();
      set_led(ok);
      if (ok) {
        spdlog::info("ready");
        logged_error = false;
      } else if (!logged_error) {
        spdlog::warn("not ready: {} (retrying)", why.message);
        logged_error = true;
      }
    }
    int wait_ms = readiness_.ready() ? config_.link.heartbeat_ms : 500;
    cv_.wait_for(lock, std::chrono::milliseconds(wait_ms), [this] { return stopping_ || !queue_.empty(); });
    if (stopping_) break;
    if (!queue_.empty()) {
      Job job = std::move(queue_.front());
      queue_.pop_front();
      running_ = job.request;
      running_reply_ = job.reply;
      abort_ = false;
      abort_reason_ = code_name(ErrorCode::Aborted);
      lock.unlock();
      run_job(job);
      lock.lock();
      running_.reset();
      running_reply_.reset();
      continue;
    }
    if (link_.connected()) {
      lock.unlock();
      idle_status();
    }
  }
  // Shutdown while moving: a controlled stop, never an arm left running unattended.
  if (link_.connected()) {
    rbx1_status_resp st{};
    if (link_.status(st) == 0 && st.state == RBX1_STATE_MOVING) {
      rbx1_stop_resp sr{};
      link_.stop(sr);
    }
  }
}

void Machine::idle_status() {
  // Idle heartbeat: a STATUS keeps the firmware's heartbeat fed and the status cache fresh.
  rbx1_status_resp st{};
  if (int r = link_.status(st); r < 0) {
    spdlog::warn("link: idle STATUS failed: {}", link::error_text(r));
    return;
  }
  // A reset board (power, watchdog, USB re-plug) no longer knows where the arm is; neither does the daemon.
  // Declaring the home pose again is the operator's call, not ours.
  std::lock_guard lock(mutex_);
  note_same_firmware(st);
  set_led(readiness_.ready() && st.state != RBX1_STATE_FAULT);  // lit exactly while status says ready
}

void Machine::run_job(Job& job) {
  Reply& reply = *job.reply;
  reply.event("job_started", request_json(job.request));
  auto started = Clock::now();
  job_deadline_ns_ = mono_ns() + int64_t(config_.daemon.job_timeout_s * 1e9);
  if (JobHandler run = job_handler(job.request.command)) run(*this, reply, job.request);
  else reply.error(ErrorCode::BadRequest, "not a job");
  if (!reply.finished()) reply.error(ErrorCode::Internal, "job ended without a result");
  spdlog::info("job {} ended after {:.2f} s", command_name(job.request.command),
               std::chrono::duration<double>(Clock::now() - started).count());
}

bool Machine::ready(Reply& reply) {
  {
    std::lock_guard lock(mutex_);
    if (readiness_.ready() && link_.connected()) return true;
    if (readiness_.held()) {
      reply.error(job_error(readiness_.state()), readiness_.reason());
      return false;
    }
  }
  // The worker retries in the background; a job waits a moment for a link that is just coming up.
  NotReady why;
  if (try_prepare(why)) return true;
  reply.error(job_error(why.state), why.message);
  return false;
}

MotionHooks Machine::hooks(Reply& reply) {
  MotionHooks h;
  h.emit = [&reply](const std::string& name, nlohmann::json fields) { reply.event(name, std::move(fields)); };
  h.aborted = [this] { return abort_.load() || mono_ns() > job_deadline_ns_.load(); };
  h.abort_reason = [this] {
    std::lock_guard lock(mutex_);
    return abort_.load() ? abort_reason_ : std::string(code_name(ErrorCode::Timeout));
  };
  h.on_status = [this](const rbx1_status_resp& s) { note_status(s); };
  return h;
}

bool Machine::run_steps(Reply& reply, const std::vector<MotionStep>& steps, MotionResult& result) {
  Motion motion(link_, {config_.daemon.status_poll_ms, config_.daemon.move_timeout_s, config_.daemon.reconnect_timeout_s});
  result = motion.run(steps, hooks(reply));
  if (result.failed_with(ErrorCode::FirmwareReset)) {
    std::lock_guard lock(mutex_);
    hold("the firmware was reset or replaced during the job (" + result.message + ")");
  }
  if (!result.ok && !result.failed_with(ErrorCode::Estop) && link_.connected()) {
    // A failed job (timeout, shutdown, a refused step) leaves nothing running behind it: STOP flushes what it
    // queued. The e-stop already halted everything.
    rbx1_stop_resp sr{};
    if (int r = link_.stop(sr); r < 0) spdlog::warn("job failed ({}): STOP not acknowledged: {}", result.code, link::error_text(r));
  }
  if (!result.ok) {
    if (result.failed_with(ErrorCode::Estop)) reply.event("estop", {{"source", estop_source()}, {"firmware", status_json(result.last)}});
    reply.error(result.code, result.message);
    return false;
  }
  return true;
}

bool Machine::move_to(Reply& reply, const std::string& name, const arm::Joints& pose) {
  MotionResult result;
  return move_to(reply, name, pose, result);
}

bool Machine::move_to(Reply& reply, const std::string& name, const arm::Joints& pose, MotionResult& result) {
  rbx1_status_resp st{};
  {
    std::lock_guard lock(mutex_);
    if (last_status_) st = *last_status_;
  }
  std::vector<MotionStep> steps;
  std::string error;
  if (!plan_pose_move(config_.arm, st, name, pose, steps, error)) {
    reply.error(ErrorCode::PlanFailed, error);
    return false;
  }
  return run_steps(reply, steps, result);
}

bool Machine::plan_pick(const vision::Scan& scan, const vision::ScanObject& object, const std::string& place,
                        std::vector<MotionStep>& steps, nlohmann::json& info, std::string& error) {
  rbx1_status_resp st{};
  {
    std::lock_guard lock(mutex_);
    if (last_status_) st = *last_status_;
  }
  return plan_pick_steps(config_.arm, st, object, scan.image, place, steps, info, error);
}

bool Machine::capture(Reply& reply, cv::Mat& frame) {
  int r = camera_->read(frame);
  if (r < 0 || frame.empty()) {
    reply.error(ErrorCode::CameraFailed, camera_->describe() + ": capture failed: " +
                                             (r < 0 ? std::strerror(-r) : "an empty frame"));
    return false;
  }
  return true;
}

bool Machine::capture_and_detect(Reply& reply, vision::Scan& scan, std::string* report) {
  cv::Mat frame;
  if (!capture(reply, frame)) return false;
  int64_t captured_ns = mono_ns();
  reply.event("captured", {{"source", camera_->describe()}, {"width", frame.cols}, {"height", frame.rows},
                           {"mono_ns", captured_ns}});
  std::string error;
  vision::Detection det;
  cv::Mat processed;
  if (!vision_->run(frame, det, processed, error)) {
    reply.error(ErrorCode::VisionFailed, error);
    return false;
  }
  scan = vision_->scan(det);
  const nlohmann::json detections = scan;  // written once for the event, the console and the bus
  std::string text = vision_->report(det);
  if (report) *report = text;
  nlohmann::json ev{{"objects", scan.objects.size()}, {"report", text}, {"detections", detections}};
  nlohmann::json labels = nlohmann::json::array();
  for (const auto& o : scan.objects) labels.push_back(o.identity.label ? nlohmann::json(*o.identity.label) : nullptr);
  ev["labels"] = labels;
  if (!config_.daemon.annotate.empty()) {
    std::string aerr;
    bool written = false;
    try {  // OpenCV reports an unwritable path by exception: keep it inside the daemon
      written = cv::imwrite(config_.daemon.annotate, vision::annotate(processed, det, vision_->calibrated()));
    } catch (const cv::Exception& e) {
      aerr = e.what();
    }
    if (written) ev["annotated"] = config_.daemon.annotate;
    else spdlog::warn("annotate: {}: cannot write the annotated image {}", config_.daemon.annotate, aerr);
  }
  last_annotated_ = vision::annotate(processed, det, vision_->calibrated());  // also the history's scan image
  {
    std::lock_guard lock(mutex_);  // before the console hears of the scan: its 3D view asks for the scene then
    last_detections_ = detections;
  }
  if (on_scan_) on_scan_(last_annotated_, detections);  // before the event
  bus_.publish(Topic::Scans, {{"ts", iso_now()}, {"detections", detections}},
               std::make_shared<const vision::Scan>(scan));
  reply.event("detected", ev);
  return true;
}

// ---- jobs -------------------------------------------------------------------------------------------------

void Machine::job_scan(Reply& reply) {
  if (!ready(reply)) return;
  if (!move_to(reply, "scan_pose", config_.arm.scan)) return;
  vision::Scan scan;
  std::string report;
  if (!capture_and_detect(reply, scan, &report)) return;
  reply.result({{"objects", scan.objects.size()}, {"report", report}, {"detections", scan}});
}

void Machine::job_home(Reply& reply) {
  if (!ready(reply)) return;
  MotionResult result;  // its last STATUS is the one that showed the move complete
  if (!move_to(reply, "home", config_.arm.home, result)) return;
  const rbx1_status_resp& st = result.last;
  reply.result({{"home", true}, {"position", std::vector<int32_t>(st.position, st.position + RBX1_JOINTS)}});
}

void Machine::job_clear_fault(Reply& reply) {
  if (!link_.connected()) {
    NotReady why;
    if (!prepare(why) && !link_.connected()) {
      reply.error(ErrorCode::NotReady, why.message);
      return;
    }
  }
  rbx1_clear_fault_resp cf{};
  int r = link_.clear_fault(cf);
  if (r < 0) {
    reply.error(ErrorCode::LinkDown, link::failed(link_.name(), "CLEAR_FAULT", r));
    return;
  }
  if (cf.status != RBX1_OK) {
    reply.error(cf.status == RBX1_ESTOP_ACTIVE ? ErrorCode::EstopActive : ErrorCode::Fault,
                std::string("CLEAR_FAULT refused: ") + rbx1_status_name(cf.status) +
                    (cf.status == RBX1_ESTOP_ACTIVE ? " (release the e-stop input first)" : ""));
    return;
  }
  reply.event("fault_cleared");
  {
    std::lock_guard lock(mutex_);
    readiness_.release();  // the operator's word that the arm stands where home_on_start will declare it
    session_ = false;
  }
  NotReady why;
  bool ok = try_prepare(why);
  {
    std::lock_guard lock(estop_mu_);
    last_estop_.clear();
  }
  if (!ok) {
    reply.error(ErrorCode::NotReady, why.message);
    return;
  }
  rbx1_status_resp st{};
  {
    std::lock_guard lock(mutex_);
    st = *last_status_;  // prepare() succeeded: its last STATUS was read and noted
  }
  reply.result({{"cleared", true}, {"firmware", status_json(st)}});
}

namespace {

// Objects that resemble `name` but are not taken as it (issue 27: an untaught look-alike stays unknown): the
// object whose best match is `name` below that entry's learnt threshold, or ambiguous with another taught
// entry, and the object that matches another taught entry better. For the object_absent message.
std::string look_alikes(const std::vector<vision::ScanObject>& objects, const std::string& name) {
  std::string out;
  char line[160];
  for (const auto& o : objects) {
    const vision::Identity& id = o.identity;
    const std::string best = id.best.value_or(""), second = id.runner_up.value_or("");
    const double score = id.best_score.value_or(0), threshold = id.threshold.value_or(0);
    if (best == name && id.verdict == vision::Verdict::BelowThreshold)
      std::snprintf(line, sizeof line, "#%d matches it %.2f, below its taught %.2f", o.index, score, threshold);
    else if (best == name && id.verdict == vision::Verdict::Ambiguous)
      std::snprintf(line, sizeof line, "#%d matches it %.2f, as well as \"%s\" %.2f", o.index, score, second.c_str(),
                    id.runner_up_score.value_or(0));
    else if (second == name && id.label)
      std::snprintf(line, sizeof line, "#%d matches it %.2f, \"%s\" better %.2f", o.index,
                    id.runner_up_score.value_or(0), best.c_str(), score);
    else
      continue;
    out += (out.empty() ? "" : "; ") + std::string(line);
  }
  return out;
}

}  // namespace

bool Machine::look_over(Reply& reply, cv::Size image, const vision::ScanObject& object, vision::Detection& det,
                        int& under, bool& looked) {
  under = -1;
  looked = false;
  const cv::Point2d centre(image.width / 2.0, image.height / 2.0);
  const auto at = table_point(config_.arm, object.centroid_px, vision_->table_cm(object.centroid_px));
  const auto middle = table_point(config_.arm, centre, vision_->table_cm(centre));
  arm::Joints look{};
  std::string error = "vision is uncalibrated";
  if (!at || !middle || !look_pose(config_.arm, *at - *middle, look, error)) {
    reply.event("second_look", {{"index", object.index}, {"skipped", error}});
    return true;
  }
  reply.event("second_look", {{"index", object.index}, {"score", vision::number_json(object.identity.best_score)},
                              {"over_mm", {std::round(at->x()), std::round(at->y())}}});
  cv::Mat frame, processed;
  if (!move_to(reply, "look", look) || !capture(reply, frame)) return false;
  if (!vision_->run(frame, det, processed, error)) {
    reply.error(ErrorCode::VisionFailed, error);
    return false;
  }
  looked = true;
  // The object under the view's centre (within a quarter of the frame): the one looked at.
  const cv::Point2d mid(processed.cols / 2.0, processed.rows / 2.0);
  double nearest = 0.25 * std::min(processed.cols, processed.rows);
  for (size_t i = 0; i < det.objects.size(); ++i) {
    const double d = cv::norm(det.objects[i].geometry.centroid - mid);
    if (d < nearest) nearest = d, under = int(i);
  }
  return true;
}

bool Machine::look_again(Reply& reply, const vision::Scan& scan, const vision::ScanObject& object,
                         const std::string& name, std::optional<bool>& taken) {
  taken.reset();
  // An image file or folder shows the same wherever the arm is; an object under the camera was seen from above.
  const cv::Point2d centre(scan.image.width / 2.0, scan.image.height / 2.0);
  if (!camera_->moves_with_arm() ||
      cv::norm(object.centroid_px - centre) < 0.05 * std::min(scan.image.width, scan.image.height))
    return true;
  vision::Detection det;
  int under = -1;
  bool looked = false;
  if (!look_over(reply, scan.image, object, det, under, looked)) return false;
  if (!looked) return true;
  const vision::Scan seen = vision_->scan(det);
  const vision::ScanObject* below = under >= 0 ? &seen.objects[size_t(under)] : nullptr;
  taken = below && below->identity.label == name;
  reply.event("second_look_seen",
              {{"index", object.index}, {"name", name},
               {"seen_as", below && below->identity.label ? nlohmann::json(*below->identity.label) : nullptr},
               {"score", below ? vision::number_json(below->identity.best_score) : nullptr}, {"taken", *taken}});
  return true;
}

bool Machine::look_before_picking(Reply& reply, const vision::Scan& scan, const std::string& name,
                                  const vision::ScanObject*& best, std::string& refused) {
  const vision::ScanObject* object = best;
  for (const auto& o : scan.objects)  // none named: the unlabelled object whose best match is the name
    if (!best && !o.identity.label && o.identity.best == name &&
        (!object || o.identity.best_score.value_or(0) > object->identity.best_score.value_or(0)))
      object = &o;
  if (!object) return true;
  std::optional<bool> taken;
  if (!look_again(reply, scan, *object, name, taken)) return false;
  if (!taken) return true;  // no look (out of reach): the first view's verdict stands
  if (!*taken) {
    char text[120];
    std::snprintf(text, sizeof text, "#%d was not \"%s\" seen from straight above", object->index, name.c_str());
    refused = text;
  }
  best = *taken ? object : nullptr;
  return true;
}

void Machine::job_pick(Reply& reply, const std::string& name, const std::string& place) {
  if (!config_.arm.places.count(place)) {
    std::string known;
    for (const auto& [k, v] : config_.arm.places) known += (known.empty() ? "" : ", ") + k;
    reply.error(ErrorCode::UnknownPlace, "no place \"" + place + "\" in [arm] places (known: " + known + ")");
    return;
  }
  if (!ready(reply)) return;
  // The paper's sequence: scan pose, capture, detect, identify.
  if (!move_to(reply, "scan_pose", config_.arm.scan)) return;
  vision::Scan scan;
  if (!capture_and_detect(reply, scan)) return;
  const vision::ScanObject* best = nullptr;
  std::string seen;
  for (const auto& o : scan.objects) {
    if (!o.identity.label) continue;
    seen += (seen.empty() ? "" : ", ") + *o.identity.label;
    if (*o.identity.label == name && (!best || o.identity.score.value_or(0) > best->identity.score.value_or(0)))
      best = &o;
  }
  std::string refused;  // what the second look did not take, for the absent message
  if (!look_before_picking(reply, scan, name, best, refused)) return;
  if (!best) {
    // Absent: back home, then report the error naming the object (the paper's rule).
    std::string alike = look_alikes(scan.objects, name);
    if (!refused.empty()) alike += (alike.empty() ? "" : "; ") + refused;
    reply.event("absent", {{"name", name}, {"seen", seen}, {"look_alikes", alike}});
    if (!move_to(reply, "home", config_.arm.home)) return;
    reply.error(ErrorCode::ObjectAbsent, "object \"" + name + "\" is not in the scene" +
                                     (seen.empty() ? std::string(" (no known object seen)") : " (seen: " + seen + ")") +
                                     (alike.empty() ? "" : "; not taken as it: " + alike));
    return;
  }
  reply.event("identified", {{"name", name}, {"index", best->index}, {"match_score", vision::number_json(best->identity.score)},
                             {"centroid_cm", vision::point_json(best->centroid_cm)}, {"grip", best->grip}});
  std::vector<MotionStep> steps;
  nlohmann::json plan_info;
  std::string error;
  if (!plan_pick(scan, *best, place, steps, plan_info, error)) {
    reply.event("unreachable", {{"name", name}, {"reason", error}});
    if (!move_to(reply, "home", config_.arm.home)) return;
    reply.error(ErrorCode::PlanFailed, "cannot pick \"" + name + "\": " + error);
    return;
  }
  plan_info["steps"] = steps.size();
  reply.event("planned", plan_info);
  MotionResult result;
  if (!run_steps(reply, steps, result)) return;
  nlohmann::json r{{"picked", name}, {"place", place}, {"steps", steps.size()},
                   {"position", std::vector<int32_t>(result.last.position, result.last.position + RBX1_JOINTS)},
                   {"link_recoveries", result.recovered}, {"resent_after_heartbeat_loss", result.resent}};
  if (config_.daemon.verify_pick && !check_pick(reply, name, place, *best, scan.objects.size(), r)) return;
  reply.result(r);
}

}  // namespace rbx1::daemon
