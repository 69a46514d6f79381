// live_view.hpp - the console's pictures: the last scan's annotated image (Figure 20) and its detections, and the
// live camera view, grabbed and JPEG-encoded once per frame by one thread however many browsers watch.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "frame_source.hpp"

namespace rbx1::console {

using Jpeg = std::shared_ptr<const std::string>;

struct LiveStats {
  uint64_t frames = 0;         // live frames grabbed and encoded
  uint64_t grab_cpu_ns = 0;    // the grabber thread's CPU time for them (read + encode)
  uint64_t encode_cpu_ns = 0;  // of which JPEG encoding
  uint64_t failures = 0;       // camera reads that failed
  int viewers = 0;             // live streams open now
};

class LiveView {
 public:
  LiveView(camera::FrameSource* camera, double fps, int jpeg_quality);
  ~LiveView();

  // The scan hook (worker thread): keeps the annotated image (encoded once) and the detection JSON.
  void set_scan(const cv::Mat& annotated, const nlohmann::json& detections);
  // The last scan: false before the first one. png: encoded on demand.
  bool scan_jpeg(Jpeg& out) const;
  bool scan_png(std::string& out) const;
  nlohmann::json scan_detections() const;  // null before the first scan
  uint64_t scan_count() const;

  // One fresh frame, encoded now (camera errors: false + error).
  bool grab_once(Jpeg& out, std::string& error);

  // A live stream holds a Viewer while it runs: the grabber thread runs while at least one does.
  class Viewer {
   public:
    explicit Viewer(LiveView& v);
    ~Viewer();
    // The next frame newer than the one it returned last; waits up to timeout. false on timeout or stop.
    bool next(Jpeg& out, std::chrono::milliseconds timeout);

   private:
    LiveView& view_;
    uint64_t seen_ = 0;
  };

  LiveStats stats() const;
  void stop();

 private:
  void grabber();
  bool encode(const cv::Mat& frame, std::string& out, uint64_t* cpu_ns) const;

  camera::FrameSource* camera_;
  double fps_;
  int quality_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  // last scan
  Jpeg scan_jpeg_;
  cv::Mat scan_image_;
  nlohmann::json scan_detections_;
  uint64_t scan_count_ = 0;
  // live
  Jpeg frame_;
  uint64_t frame_seq_ = 0;
  int viewers_ = 0;
  bool grabbing_ = false;  // the grabber thread is in its loop
  bool stopping_ = false;
  LiveStats stats_;
  std::thread thread_;
};

}  // namespace rbx1::console
