// v4l2_capture.hpp - a V4L2 video capture device with mmap streaming (YUYV or MJPEG).
#pragma once
#include <string>
#include <vector>

#include "frame_source.hpp"

namespace rbx1::camera {

class V4L2Capture : public FrameSource {
 public:
  ~V4L2Capture() override;
  // Opens, sets format and rate, maps buffers and starts streaming. 0 or a negative errno with error set.
  int open(const CameraConfig& config, std::string& error);
  int read(cv::Mat& bgr) override;
  std::string describe() const override;

 private:
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };
  int fail(std::string& error, const std::string& what, int err);
  void close();

  std::string device_;
  int fd_ = -1;
  uint32_t pixfmt_ = 0;
  int width_ = 0, height_ = 0, fps_ = 0;
  size_t bytesperline_ = 0;
  std::vector<Buffer> buffers_;
  bool streaming_ = false;
};

}  // namespace rbx1::camera
