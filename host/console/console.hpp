// console.hpp - the web console: an HTTP server inside rbx1d whose JSON endpoints are requests to the same handler
// as the control socket, plus the page, the pictures (Figure 20, live view) and the live event log.
#pragma once
#include <functional>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "bus.hpp"
#include "console_config.hpp"
#include "frame_source.hpp"
#include "reply.hpp"

namespace rbx1::console {

class Console {
 public:
  // submit: the control socket's request handler (Machine::handle); it ends each reply, now or from a job.
  using Submit = daemon::Handler;
  // bus: the daemon's bus, whose events (every client's requests) the event log shows.
  // info: what the page shows as it is (GET /api/info), e.g. {"places": [...]}.
  Console(ConsoleConfig config, Submit submit, daemon::Bus& bus, camera::FrameSource* camera, double job_timeout_s,
          nlohmann::json info = nlohmann::json::object());
  ~Console();
  // Binds config.bind and serves on its own threads. 0, or a negative errno with error ("127.0.0.1:8080: ...").
  int start(std::string& error);
  void stop();
  int port() const;  // the bound port (config port 0: the one the kernel chose)
  std::string url() const;
  // The daemon's scan hook: the annotated image (Figure 20) and the detection JSON of each scan.
  void scan_done(const cv::Mat& annotated, const nlohmann::json& detections);
  // The history's scan images (STATE_DIR/scans, host/history): GET /api/history/scan/ID.jpg (set before start()).
  void serve_scans(std::string dir);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rbx1::console
