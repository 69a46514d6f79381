// frame_source.hpp - where frames come from: a V4L2 camera, an image file, a folder of images, or a frame server.
#pragma once
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "config.hpp"

namespace rbx1::camera {

struct CameraConfig {
  std::string device;  // /dev/videoN, an image file, a folder of images, or unix:SOCKET (a frame server)
  int width = 1280, height = 720, fps = 30;
  std::string format = "YUYV";  // YUYV or MJPEG (V4L2 only)
};
void parse_camera_config(rbx1::config::Section camera, CameraConfig& out);  // the [camera] table

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual int read(cv::Mat& bgr) = 0;  // 0 or a negative errno
  virtual std::string describe() const = 0;
  // Whether the camera rides on the arm (the paper's camera on the end effector: a V4L2 device, rbx1-world's),
  // so that moving the arm moves the view; an image file or a folder shows what it holds wherever the arm is.
  virtual bool moves_with_arm() const { return false; }
};

// "/dev/videoN" (any character device) -> V4L2 mmap streaming (YUYV or MJPEG); an image file -> that image on
// every read; a folder -> its images in name order, cycling; "unix:PATH" -> a frame server on that Unix socket
// (socket_source.hpp, e.g. rbx1-world). null + error "PATH: reason" when it cannot be opened.
std::unique_ptr<FrameSource> open_source(const CameraConfig&, std::string& error);

}  // namespace rbx1::camera
