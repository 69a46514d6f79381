// v4l2_capture.hpp - a V4L2 video capture device with mmap streaming (YUYV or MJPEG).
#pragma once
#include <cstddef>
#include <poll.h>
#include <string>
#include <sys/types.h>
#include <vector>

#include "frame_source.hpp"

namespace rbx1::camera {

// The kernel calls V4L2Capture makes (each as the libc call: -1 and errno on failure), so a test can stand in
// a fake driver where no /dev/video exists.
struct VideoSyscalls {
  int (*open)(const char* path, int flags);
  int (*close)(int fd);
  int (*ioctl)(int fd, unsigned long request, void* arg);
  void* (*mmap)(void* addr, size_t length, int prot, int flags, int fd, off_t offset);
  int (*munmap)(void* addr, size_t length);
  int (*poll)(pollfd* fds, nfds_t n, int timeout_ms);
};
const VideoSyscalls& system_video_syscalls();

class V4L2Capture : public FrameSource {
 public:
  explicit V4L2Capture(const VideoSyscalls& sys = system_video_syscalls()) : sys_(sys) {}
  ~V4L2Capture() override;
  // Opens, sets format and rate, maps buffers and starts streaming. 0 or a negative errno with error set.
  int open(const CameraConfig& config, std::string& error);
  int read(cv::Mat& bgr) override;
  std::string describe() const override;
  bool moves_with_arm() const override { return true; }

 private:
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };
  int fail(std::string& error, const std::string& what, int err, bool say_errno = true);
  void close();

  int xioctl(unsigned long request, void* arg);

  const VideoSyscalls& sys_;
  std::string device_;
  int fd_ = -1;
  uint32_t pixfmt_ = 0;
  int width_ = 0, height_ = 0, fps_ = 0;
  size_t bytesperline_ = 0;
  std::vector<Buffer> buffers_;
  bool streaming_ = false;
};

}  // namespace rbx1::camera
