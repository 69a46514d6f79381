// v4l2_capture.cpp - QUERYCAP, S_FMT, S_PARM, REQBUFS/QUERYBUF/mmap, QBUF/STREAMON, DQBUF per frame.
#include "v4l2_capture.hpp"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "convert.hpp"

namespace rbx1::camera {

namespace {

constexpr unsigned kBuffers = 4;
constexpr int kFrameTimeoutMs = 2000;

int sys_open(const char* path, int flags) { return ::open(path, flags); }
int sys_ioctl(int fd, unsigned long request, void* arg) { return ::ioctl(fd, request, arg); }

std::string fourcc(uint32_t f) {
  return {char(f & 0xFF), char((f >> 8) & 0xFF), char((f >> 16) & 0xFF), char((f >> 24) & 0xFF)};
}

}  // namespace

const VideoSyscalls& system_video_syscalls() {
  static const VideoSyscalls sys{sys_open, ::close, sys_ioctl, ::mmap, ::munmap, ::poll};
  return sys;
}

V4L2Capture::~V4L2Capture() { close(); }

int V4L2Capture::xioctl(unsigned long request, void* arg) {
  int r;
  do r = sys_.ioctl(fd_, request, arg);
  while (r < 0 && errno == EINTR);
  return r < 0 ? -errno : 0;
}

int V4L2Capture::fail(std::string& error, const std::string& what, int err, bool say_errno) {
  error = device_ + ": " + what + (say_errno ? std::string(" (") + std::strerror(-err) + ")" : std::string());
  close();
  return err;
}

void V4L2Capture::close() {
  if (fd_ < 0) return;
  if (streaming_) {
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  for (Buffer& b : buffers_)
    if (b.start) sys_.munmap(b.start, b.length);
  buffers_.clear();
  sys_.close(fd_);
  fd_ = -1;
}

int V4L2Capture::open(const CameraConfig& config, std::string& error) {
  device_ = config.device;
  fd_ = sys_.open(device_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    int e = errno;
    error = device_ + ": " + std::strerror(e);
    return -e;
  }
  v4l2_capability cap{};
  if (int r = xioctl(VIDIOC_QUERYCAP, &cap); r < 0) return fail(error, "not a V4L2 device", r);
  uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) return fail(error, "not a video capture device", -ENODEV, false);
  if (!(caps & V4L2_CAP_STREAMING)) return fail(error, "does not support streaming I/O", -ENOTSUP, false);

  pixfmt_ = config.format == "MJPEG" ? V4L2_PIX_FMT_MJPEG : V4L2_PIX_FMT_YUYV;
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<uint32_t>(config.width);
  fmt.fmt.pix.height = static_cast<uint32_t>(config.height);
  fmt.fmt.pix.pixelformat = pixfmt_;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (int r = xioctl(VIDIOC_S_FMT, &fmt); r < 0) return fail(error, "VIDIOC_S_FMT " + config.format, r);
  if (fmt.fmt.pix.pixelformat != pixfmt_)
    return fail(error, "does not offer " + config.format + " (driver chose " + fourcc(fmt.fmt.pix.pixelformat) + ")",
                -EINVAL, false);
  width_ = static_cast<int>(fmt.fmt.pix.width);
  height_ = static_cast<int>(fmt.fmt.pix.height);
  bytesperline_ = fmt.fmt.pix.bytesperline;
  if (width_ != config.width || height_ != config.height)
    spdlog::warn("{}: asked for {}x{}, the driver gives {}x{}", device_, config.width, config.height, width_, height_);

  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  parm.parm.capture.timeperframe = {1, static_cast<uint32_t>(config.fps)};
  fps_ = config.fps;
  if (xioctl(VIDIOC_S_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator)
    fps_ = static_cast<int>(parm.parm.capture.timeperframe.denominator / parm.parm.capture.timeperframe.numerator);
  else
    spdlog::warn("{}: cannot set the frame rate; using the driver's", device_);

  v4l2_requestbuffers req{};
  req.count = kBuffers;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (int r = xioctl(VIDIOC_REQBUFS, &req); r < 0) return fail(error, "VIDIOC_REQBUFS", r);
  if (req.count < 2) return fail(error, "too few capture buffers", -ENOMEM, false);
  buffers_.resize(req.count);
  for (unsigned i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (int r = xioctl(VIDIOC_QUERYBUF, &buf); r < 0) return fail(error, "VIDIOC_QUERYBUF", r);
    void* p = sys_.mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (p == MAP_FAILED) return fail(error, "mmap", -errno);
    buffers_[i] = {p, buf.length};
    if (int r = xioctl(VIDIOC_QBUF, &buf); r < 0) return fail(error, "VIDIOC_QBUF", r);
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (int r = xioctl(VIDIOC_STREAMON, &type); r < 0) return fail(error, "VIDIOC_STREAMON", r);
  streaming_ = true;
  spdlog::info("{}: {} {}x{} at {} fps, {} buffers ({})", device_, config.format, width_, height_, fps_,
               buffers_.size(), reinterpret_cast<const char*>(cap.card));
  return 0;
}

int V4L2Capture::read(cv::Mat& bgr) {
  if (fd_ < 0) return -ENODEV;
  pollfd p{fd_, POLLIN, 0};
  int n;
  do n = sys_.poll(&p, 1, kFrameTimeoutMs);
  while (n < 0 && errno == EINTR);
  if (n < 0) return -errno;
  if (n == 0) {
    spdlog::error("{}: no frame within {} ms", device_, kFrameTimeoutMs);
    return -ETIMEDOUT;
  }
  if (p.revents & (POLLERR | POLLHUP)) {
    spdlog::error("{}: device error or unplugged", device_);
    return -ENODEV;
  }
  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (int r = xioctl(VIDIOC_DQBUF, &buf); r < 0) {
    if (r != -EAGAIN) spdlog::error("{}: VIDIOC_DQBUF: {}", device_, std::strerror(-r));
    return r;
  }
  const uint8_t* data = static_cast<const uint8_t*>(buffers_[buf.index].start);
  int r = (buf.flags & V4L2_BUF_FLAG_ERROR) ? -EIO
          : pixfmt_ == V4L2_PIX_FMT_MJPEG
              ? mjpeg_to_bgr(data, buf.bytesused, bgr)
              : yuyv_to_bgr(data, buf.bytesused, width_, height_, bytesperline_, bgr);
  if (int q = xioctl(VIDIOC_QBUF, &buf); q < 0) spdlog::error("{}: VIDIOC_QBUF: {}", device_, std::strerror(-q));
  if (r < 0) spdlog::warn("{}: dropped a bad frame ({})", device_, std::strerror(-r));
  return r;
}

std::string V4L2Capture::describe() const {
  return device_ + " (V4L2 " + fourcc(pixfmt_) + " " + std::to_string(width_) + "x" + std::to_string(height_) +
         " at " + std::to_string(fps_) + " fps)";
}

}  // namespace rbx1::camera
