// live_view.cpp - last scan image, one-shot frames, and the shared live grabber (paced, started on demand).
#include "live_view.hpp"

#include <cstring>
#include <time.h>

#include <algorithm>

#include <opencv2/imgcodecs.hpp>

namespace rbx1::console {

namespace {
uint64_t thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return uint64_t(ts.tv_sec) * 1000000000ull + uint64_t(ts.tv_nsec);
}
}  // namespace

LiveView::LiveView(camera::FrameSource* camera, double fps, int jpeg_quality)
    : camera_(camera), fps_(fps), quality_(jpeg_quality) {}

LiveView::~LiveView() { stop(); }

void LiveView::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool LiveView::encode(const cv::Mat& frame, std::string& out, uint64_t* cpu_ns) const {
  uint64_t t0 = cpu_ns ? thread_cpu_ns() : 0;
  std::vector<uchar> buf;
  bool ok = false;
  try {
    ok = cv::imencode(".jpg", frame, buf, {cv::IMWRITE_JPEG_QUALITY, quality_});
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (cpu_ns) *cpu_ns = thread_cpu_ns() - t0;
  out.assign(buf.begin(), buf.end());
  return ok;
}

void LiveView::set_scan(const cv::Mat& annotated, const nlohmann::json& detections) {
  auto jpeg = std::make_shared<std::string>();
  encode(annotated, *jpeg, nullptr);
  std::lock_guard lock(mutex_);
  scan_jpeg_ = std::move(jpeg);
  scan_image_ = annotated.clone();
  scan_detections_ = detections;
  ++scan_count_;
}

bool LiveView::scan_jpeg(Jpeg& out) const {
  std::lock_guard lock(mutex_);
  out = scan_jpeg_;
  return out != nullptr;
}

bool LiveView::scan_png(std::string& out) const {
  cv::Mat image;
  {
    std::lock_guard lock(mutex_);
    image = scan_image_;
  }
  if (image.empty()) return false;
  std::vector<uchar> buf;
  if (!cv::imencode(".png", image, buf)) return false;
  out.assign(buf.begin(), buf.end());
  return true;
}

nlohmann::json LiveView::scan_detections() const {
  std::lock_guard lock(mutex_);
  return scan_detections_;
}

uint64_t LiveView::scan_count() const {
  std::lock_guard lock(mutex_);
  return scan_count_;
}

bool LiveView::grab_once(Jpeg& out, std::string& error) {
  cv::Mat frame;
  int r = camera_->read(frame);
  if (r < 0 || frame.empty()) {
    error = camera_->describe() + ": capture failed: " + (r < 0 ? std::strerror(-r) : "an empty frame");
    return false;
  }
  auto jpeg = std::make_shared<std::string>();
  if (!encode(frame, *jpeg, nullptr)) {
    error = "cannot encode the frame as JPEG";
    return false;
  }
  out = std::move(jpeg);
  return true;
}

LiveView::Viewer::Viewer(LiveView& v) : view_(v) {
  std::lock_guard lock(v.mutex_);
  ++v.viewers_;
  if (!v.grabbing_ && !v.stopping_) {
    if (v.thread_.joinable()) v.thread_.join();  // a grabber that left its loop: it needs the lock no more
    v.grabbing_ = true;
    v.thread_ = std::thread([&v] { v.grabber(); });
  }
}

LiveView::Viewer::~Viewer() {
  std::lock_guard lock(view_.mutex_);
  --view_.viewers_;
  view_.cv_.notify_all();
}

bool LiveView::Viewer::next(Jpeg& out, std::chrono::milliseconds timeout) {
  std::unique_lock lock(view_.mutex_);
  view_.cv_.wait_for(lock, timeout, [&] { return view_.stopping_ || view_.frame_seq_ > seen_; });
  if (view_.stopping_ || view_.frame_seq_ <= seen_) return false;
  seen_ = view_.frame_seq_;
  out = view_.frame_;
  return true;
}

LiveStats LiveView::stats() const {
  std::lock_guard lock(mutex_);
  LiveStats s = stats_;
  s.viewers = viewers_;
  return s;
}

void LiveView::grabber() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / fps_));
  auto next = Clock::now();
  cv::Mat frame;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      // Pace: wait for the frame's slot; leave when nobody watches (the next viewer starts a new thread).
      cv_.wait_until(lock, next, [&] { return stopping_ || viewers_ == 0; });
      if (stopping_ || viewers_ == 0) {
        grabbing_ = false;
        return;
      }
    }
    next = std::max(next + period, Clock::now());
    uint64_t t0 = thread_cpu_ns();
    int r = camera_->read(frame);
    auto jpeg = std::make_shared<std::string>();
    uint64_t encode_ns = 0;
    bool ok = r == 0 && !frame.empty() && encode(frame, *jpeg, &encode_ns);
    uint64_t spent = thread_cpu_ns() - t0;
    std::lock_guard lock(mutex_);
    if (!ok) {
      ++stats_.failures;
      continue;
    }
    frame_ = std::move(jpeg);
    ++frame_seq_;
    ++stats_.frames;
    stats_.grab_cpu_ns += spent;
    stats_.encode_cpu_ns += encode_ns;
    cv_.notify_all();
  }
}

}  // namespace rbx1::console
