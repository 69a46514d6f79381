// locked_source.hpp - a FrameSource shared between threads (the daemon's jobs and the web console's live view).
#pragma once
#include <memory>
#include <mutex>
#include <string>

#include "frame_source.hpp"

namespace rbx1::camera {

// Serialises read() of the wrapped source: one frame at a time, whoever asks.
class LockedSource : public FrameSource {
 public:
  explicit LockedSource(std::unique_ptr<FrameSource> inner) : inner_(std::move(inner)) {}
  int read(cv::Mat& bgr) override {
    std::lock_guard lock(mutex_);
    return inner_->read(bgr);
  }
  std::string describe() const override { return inner_->describe(); }
  bool moves_with_arm() const override { return inner_->moves_with_arm(); }

 private:
  std::unique_ptr<FrameSource> inner_;
  std::mutex mutex_;
};

}  // namespace rbx1::camera
