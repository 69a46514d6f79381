// machine.hpp - the arm as a job runner: one worker thread owns the link, the camera and the vision pipeline and
// runs one job at a time (scan, pick, home, clear_fault); status and e-stop are served at once from any thread.
#pragma once
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "bus.hpp"
#include "bus_stream.hpp"
#include "daemon_setup.hpp"
#include "history.hpp"
#include "motion.hpp"
#include "readiness.hpp"
#include "server.hpp"
#include "state_dir.hpp"
#include "workspace_session.hpp"

namespace rbx1::daemon {

class Machine {
 public:
  // estop_source / start_source / status_led: the e-stop line's and the start button's edges, and the LED, from a
  // test or bench (gpio::SimEdgeSource, gpio::SimOutputLine) instead of [gpio] estop / start_button / status_led.
  explicit Machine(Config config, std::unique_ptr<gpio::EdgeSource> estop_source = nullptr,
                   std::unique_ptr<gpio::EdgeSource> start_source = nullptr,
                   std::unique_ptr<gpio::OutputLine> status_led = nullptr);
  ~Machine();

  // Opens the camera and the vision pipeline (errors are fatal: bad files), starts the GPIO watcher and the
  // worker, which connects the link in the background (and keeps retrying while the port is absent).
  int start(std::string& error);
  // The control socket's handler (server thread).
  void handle(const Request& request, std::shared_ptr<Reply> reply);
  // One request through handle() in-process (tests, the latency probe): its final line, null on timeout.
  nlohmann::json call(Command command, int timeout_ms = 30000);
  // E-stop from any source ("control", "gpio"): ESTOP on the wire first, then the job is aborted.
  void estop(const std::string& source);
  // The start button was pressed: when idle, queues `pick [daemon] start_pick --place start_place` (its events go
  // to the log); while a job runs, or without a start_pick, the press is ignored with a log line.
  void start_pressed();
  // Stops the worker: a running job is aborted with a controlled STOP.
  void stop();
  // Called (server thread) when a shutdown request arrives, after its reply.
  void on_shutdown(std::function<void()> f) { on_shutdown_ = std::move(f); }
  // The web console's hooks (set before start()): each scan's annotated image (Figure 20) and detection JSON
  // (worker thread), and the camera, whose reads are serialised with the jobs' (valid after start()).
  using ScanHook = std::function<void(const cv::Mat& annotated, const nlohmann::json& detections)>;
  void on_scan(ScanHook f) { on_scan_ = std::move(f); }
  camera::FrameSource* camera() { return camera_.get(); }
  // The status and event bus: every request's lines but reads, status on change (at least every 2 s), each scan.
  Bus& bus() { return bus_; }

  // Each command of the command table (command_table.cpp) has its handler here (command_handlers.cpp): a job's
  // runs on the worker, one at a time; an immediate one's at once on the caller's thread, ending the reply now or
  // later. Adding a command is its table entry, its line in command_handlers.cpp and the function it calls.
  using JobHandler = void (*)(Machine& m, Reply& reply, const Request& request);
  using ImmediateHandler = void (*)(Machine& m, const Request& request, std::shared_ptr<Reply> reply);
  static JobHandler job_handler(Command c);              // null for an immediate command
  static ImmediateHandler immediate_handler(Command c);  // null for a job

 private:
  struct Job {
    Request request;
    std::shared_ptr<Reply> reply;
  };

  void worker();
  int start_gpio(std::string& error);
  // Link open, HELLO, foreign entries stopped, enable, home/declare; false with why (readiness.hpp).
  bool prepare(NotReady& why);
  bool connect(rbx1_status_resp& st, NotReady& why);                // open or reopen, the first STATUS
  bool clear_stale_heartbeat(rbx1_status_resp& st, NotReady& why);  // a previous host session's HEARTBEAT_LOST
  bool enable_and_home(rbx1_status_resp& st, NotReady& why);        // [daemon] home_on_start when not homed
  bool home_on_switches(rbx1_status_resp& st, NotReady& why);
  bool declare_home(NotReady& why);
  bool try_prepare(NotReady& why);  // prepare() with its outcome in readiness_; true when ready
  // Notes a STATUS (mutex_ held); a firmware this daemon prepared that was since reset (firmware_reset()) puts it
  // on hold. False then.
  bool note_same_firmware(const rbx1_status_resp& st);
  void idle_status();  // the worker's STATUS between jobs (the firmware's heartbeat, the status cache)
  // The immediate commands answered here (the others: handle_jobs_request).
  void answer_subscribe(const Request& request, std::shared_ptr<Reply> reply);
  void answer_estop(Reply& reply);
  void answer_shutdown(Reply& reply);
  void run_job(Job& job);
  void job_scan(Reply& reply);
  void job_pick(Reply& reply, const std::string& name, const std::string& place);
  void job_home(Reply& reply);
  void job_clear_fault(Reply& reply);
  // Moves to a joint pose (degrees) as one step; false after reply->error.
  bool move_to(Reply& reply, const std::string& name, const arm::Joints& pose);
  bool move_to(Reply& reply, const std::string& name, const arm::Joints& pose, MotionResult& result);
  void hold(const std::string& why);  // mutex_ held: readiness Held until clear_fault
  bool run_steps(Reply& reply, const std::vector<MotionStep>& steps, MotionResult& result);
  // The pick of `object` (one of scan's objects) to `place`, planned from the last firmware status (pick_plan.hpp).
  bool plan_pick(const vision::Scan& scan, const vision::ScanObject& object, const std::string& place,
                 std::vector<MotionStep>& steps, nlohmann::json& info, std::string& error);
  std::string estop_source();  // who latched the last e-stop ("firmware" when no request or input of ours did)
  // One camera frame, or a camera_failed error on reply (false).
  bool capture(Reply& reply, cv::Mat& frame);
  // Capture + detect (the arm at the scan pose): the scan as a struct for the job; as JSON (scan_json.hpp, written
  // once) to the detected event, the console and the bus. report: the paper's Figure 21. false after reply.error.
  bool capture_and_detect(Reply& reply, vision::Scan& scan, std::string* report = nullptr);
  // A part seen off the camera's optical axis shows its side wall too, and may score under what it was taught at
  // (a tall part: a false object_absent) or as a look-alike it is not (an untaught twin turned across the lean),
  // issue 27. So when the camera rides on the arm, a pick by name looks again straight over its object before
  // taking it: the one labelled the name (unless already under the view's centre), else the unlabelled one whose
  // best match is the name. `best` is then the object of `scan` seen there as the name, or null (`refused` says
  // which was not). false after reply.error (the look's move or capture failed).
  bool look_before_picking(Reply& reply, const vision::Scan& scan, const std::string& name,
                           const vision::ScanObject*& best, std::string& refused);
  // Whether the object under the view's centre, seen straight over `object`, is labelled `name` (look_over);
  // none when no look was made or needed (a camera that does not move with the arm, the object already under the
  // camera, out of reach, uncalibrated). A pick by name and each pick of a sort ask it.
  bool look_again(Reply& reply, const vision::Scan& scan, const vision::ScanObject& object, const std::string& name,
                  std::optional<bool>& taken);
  // The camera straight over `object` of a scan pose's frame of size `image` (the scan pose's tool moved by its
  // offset from the view's centre on the table, same height and yaw), a frame and its detection `det`: `under` is
  // the index in det.objects of the object under the view's centre (within a quarter of the frame), -1 when none.
  // looked = false when the look is out of reach or vision uncalibrated (no move made). false after reply.error.
  bool look_over(Reply& reply, cv::Size image, const vision::ScanObject& object, vision::Detection& det, int& under,
                 bool& looked);
  // [daemon] verify_pick (pick_check.cpp): after a pick, a scan must no longer show the object where it was;
  // else pick_failed and, up to pick_retries times, a new pick from the fresh detection; scanned: the objects the
  // pick's own scan found (a check frame with none where it found several is blind). false after reply.error.
  bool check_pick(Reply& reply, const std::string& name, const std::string& place, vision::ScanObject picked,
                  size_t scanned, nlohmann::json& result);
  // A frame judging the pick of `name` (the check's, the sort's next scan; pick_check.cpp): capture and detect; a
  // frame with no object where the scan before found `before` >= 2 is blind (a check_blind event) and taken once
  // more. false after reply.error: the camera's or vision's, or blind twice (the arm sent home, then
  // pick_unverified).
  bool judging_scan(Reply& reply, vision::Scan& scan, size_t before, const std::string& name, int attempt);
  bool ready(Reply& reply);
  // The operator's jobs (operator_jobs.cpp) and the workspace calibration (workspace_jobs.cpp).
  void job_jog(Reply& reply, const Request& request);
  void job_pose_save(Reply& reply);
  void job_place_save(Reply& reply, const std::string& name);
  void job_background(Reply& reply, int frames);
  void job_teach(Reply& reply, const Request& request);
  void job_calibrate_workspace(Reply& reply, const Request& request);
  void workspace_start(Reply& reply, const char* in_force);  // markers at the scan pose: a new session
  void workspace_record(Reply& reply, int marker);           // the tool point now is the marker's centre
  void workspace_fit(Reply& reply, bool save);               // the map; save: written and in force
  // The cell's jobs (sort_jobs.cpp): sort by a recipe, clear to one place, each pick into the history; and the
  // requests answered at once: pause, resume, cancel, history, recipe_save, recipes (true when request was one of
  // them).
  friend class SortRun;
  void job_sort(Reply& reply, const Request& request);
  bool handle_jobs_request(const Request& request, Reply& reply);
  bool open_history(std::string& error);
  // The recipe's places are known and its classes in the library (clear: places only); else error naming one.
  bool check_recipe_here(const std::map<std::string, std::string>& recipe, bool places_only, std::string& error);
  // The names a recipe may use here: the [arm] places and the library's classes (places_only: classes = {"*"}).
  bool recipe_names(std::set<std::string>& places, std::set<std::string>& classes, bool places_only, std::string& error);
  // The camera-to-arm map in force for status: {"in_force": "mount"} or the saved workspace calibration's figures.
  nlohmann::json calibration_summary(const calib::WorkspaceCalibration* w) const;
  bool current_pose(Reply& reply, arm::Steps& steps, arm::Joints& deg);  // a fresh STATUS; false after reply.error
  bool reload_vision(Reply& reply);  // after the background or the library changed
  const char* busy_locked() const;  // the running or queued job's command, or null (mutex_ held)
  MotionHooks hooks(Reply& reply);
  nlohmann::json status_reply();
  void note_status(const rbx1_status_resp& s);
  // Under mutex_: the STATUS just read becomes last_status_, with the time it was read; a new position wakes the
  // status thread, which publishes it at once (the bus's and DDS's joints stamped with that time).
  void set_last_status(const rbx1_status_resp& s);
  void publish_status();  // status thread: the status on the bus when it changed, and at least every 2 s
  // The `scene` request: the arm's world for a 3D view (scene.hpp).
  nlohmann::json scene_reply();

  Bus bus_;  // before everything that publishes on it
  BusStreams streams_{bus_};
  std::thread status_thread_;
  std::condition_variable status_cv_;

  Config config_;
  link::Link link_;
  std::unique_ptr<camera::FrameSource> camera_;
  std::unique_ptr<vision::Vision> vision_;
  std::unique_ptr<StateDir> state_;                    // [daemon] state_dir
  std::unique_ptr<WorkspaceSession> workspace_;        // the calibration in progress (worker thread only)
  std::unique_ptr<history::History> history_;          // STATE_DIR/history.sqlite (sort_jobs.cpp)
  enum class JobControl { Run, Pause, Cancel };
  std::atomic<JobControl> job_control_{JobControl::Run};  // the running sort or clear's pause/resume/cancel
  cv::Mat last_annotated_;                             // the last scan's annotated image (worker thread)
  nlohmann::json calibration_;                         // calibration_summary of the map in force (under mutex_)
  std::unique_ptr<gpio::EdgeSource> estop_source_;
  std::unique_ptr<gpio::InputWatcher> estop_input_;
  std::unique_ptr<gpio::EdgeSource> start_source_;
  std::unique_ptr<gpio::InputWatcher> start_input_;
  std::unique_ptr<gpio::OutputLine> status_led_;
  void set_led(bool ready);

  std::thread worker_;
  std::mutex mutex_;  // guards everything below
  std::condition_variable cv_;
  std::deque<Job> queue_;
  std::optional<Request> running_;  // the job the worker is running
  std::shared_ptr<Reply> running_reply_;  // its reply: once finished, the next job may queue behind it
  bool stopping_ = false;
  ReadyState readiness_;            // ready, or why not (the status's link.error)
  bool session_ = false;            // this daemon prepared the firmware: a later reset of it is a hold, not a fresh start
  std::optional<rbx1_status_resp> last_status_;
  int64_t last_status_read_ns_ = 0;  // Unix time (ns) last_status_ was read from the firmware
  bool status_news_ = false;        // a new position for the status thread to publish
  nlohmann::json last_detections_;  // the last scan's detections (the scene's objects)
  std::mutex estop_mu_;             // guards last_estop_ only (taken before the ESTOP frame: never held long)
  std::string last_estop_;          // source of the last e-stop
  std::atomic<bool> abort_{false};
  std::function<void()> on_shutdown_;
  ScanHook on_scan_;
  std::string abort_reason_ = code_name(ErrorCode::Aborted);
  std::atomic<int64_t> job_deadline_ns_{0};  // steady clock; a job running past it is aborted ("timeout")
};

}  // namespace rbx1::daemon
