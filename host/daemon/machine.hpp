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
#include <string>
#include <thread>

#include "bus.hpp"
#include "bus_stream.hpp"
#include "daemon_setup.hpp"
#include "history.hpp"
#include "motion.hpp"
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

 private:
  struct Job {
    Request request;
    std::shared_ptr<Reply> reply;
  };

  void worker();
  int start_gpio(std::string& error);
  bool prepare(std::string& error);                // link open, HELLO, enable, home/declare
  void run_job(Job& job);
  void job_scan(Reply& reply);
  void job_pick(Reply& reply, const std::string& name, const std::string& place);
  void job_home(Reply& reply);
  void job_clear_fault(Reply& reply);
  // Moves to a joint pose (degrees) as one step; false after reply->error.
  bool move_to(Reply& reply, const std::string& name, const arm::Joints& pose);
  bool move_to(Reply& reply, const std::string& name, const arm::Joints& pose, MotionResult& result);
  void hold(const std::string& why);  // mutex_ held: not ready until clear_fault
  bool run_steps(Reply& reply, const std::vector<MotionStep>& steps, MotionResult& result);
  // The pick of `object` from `detections` to `place`, planned from the last firmware status (pick_plan.hpp).
  bool plan_pick(const nlohmann::json& detections, const nlohmann::json& object, const std::string& place,
                 std::vector<MotionStep>& steps, nlohmann::json& info, std::string& error);
  // Capture + detect at the scan pose; false after reply.error.
  std::string estop_source();  // who latched the last e-stop ("firmware" when no request or input of ours did)
  // One camera frame, or a camera_failed error on reply (false).
  bool capture(Reply& reply, cv::Mat& frame);
  bool capture_and_detect(Reply& reply, nlohmann::json& detections, std::string& report);
  // [daemon] verify_pick (pick_check.cpp): after a pick, a scan must no longer show the object where it was;
  // else pick_failed and, up to pick_retries times, a new pick from the fresh detection; scanned: the objects the
  // pick's own scan found (a check frame with none where it found several is blind). false after reply.error.
  bool check_pick(Reply& reply, const std::string& name, const std::string& place, nlohmann::json picked,
                  size_t scanned, nlohmann::json& result);
  bool ready(Reply& reply);
  // The operator's jobs (operator_jobs.cpp) and the workspace calibration (workspace_jobs.cpp).
  void job_jog(Reply& reply, const Request& request);
  void job_pose_save(Reply& reply);
  void job_place_save(Reply& reply, const std::string& name);
  void job_background(Reply& reply, int frames);
  void job_teach(Reply& reply, const Request& request);
  void job_calibrate_workspace(Reply& reply, const Request& request);
  // The cell's jobs (sort_jobs.cpp): sort by a recipe, clear to one place, each pick into the history; and the
  // requests answered at once: pause, resume, cancel, history, recipe_save (true when request was one of them).
  friend class SortRun;
  void job_sort(Reply& reply, const Request& request);
  bool handle_jobs_request(const Request& request, Reply& reply);
  bool open_history(std::string& error);
  // The recipe's places are known and its classes in the library (clear: places only); else error naming one.
  bool check_recipe_here(const std::map<std::string, std::string>& recipe, bool places_only, std::string& error);
  // The camera-to-arm map in force for status: {"in_force": "mount"} or the saved workspace calibration's figures.
  nlohmann::json calibration_summary(const calib::WorkspaceCalibration* w) const;
  bool current_pose(Reply& reply, arm::Steps& steps, arm::Joints& deg);  // a fresh STATUS; false after reply.error
  bool reload_vision(Reply& reply);  // after the background or the library changed
  const char* busy_locked() const;  // the running or queued job's command, or null (mutex_ held)
  MotionHooks hooks(Reply& reply);
  nlohmann::json status_reply();
  void note_status(const rbx1_status_resp& s);
  void publish_status();  // status thread: the status on the bus when it changed, and at least every 2 s

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
  bool prepared_ = false;           // link up, drivers enabled, positions homed or declared
  bool hold_ = false;               // the firmware lost its positions: wait for the operator (clear_fault)
  bool session_ = false;            // this daemon prepared the firmware: a later reset of it is a hold, not a fresh start
  std::string link_error_;          // why the link is not ready
  std::optional<rbx1_status_resp> last_status_;
  std::mutex estop_mu_;             // guards last_estop_ only (taken before the ESTOP frame: never held long)
  std::string last_estop_;          // source of the last e-stop
  std::atomic<bool> abort_{false};
  std::function<void()> on_shutdown_;
  ScanHook on_scan_;
  std::string abort_reason_ = "aborted";
  std::atomic<int64_t> job_deadline_ns_{0};  // steady clock; a job running past it is aborted ("timeout")
};

}  // namespace rbx1::daemon
