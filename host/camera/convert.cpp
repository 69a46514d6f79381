// convert.cpp - YUYV via cv::cvtColor, MJPEG via cv::imdecode.
#include "convert.hpp"

#include <cerrno>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rbx1::camera {

int yuyv_to_bgr(const uint8_t* data, size_t bytes, int width, int height, size_t bytesperline, cv::Mat& bgr) {
  if (width <= 0 || height <= 0 || width % 2) return -EINVAL;
  size_t stride = bytesperline ? bytesperline : size_t(width) * 2;
  if (stride < size_t(width) * 2 || bytes < stride * size_t(height - 1) + size_t(width) * 2) return -EINVAL;
  // Wraps the buffer without copying; cvtColor writes the result into bgr.
  cv::Mat yuyv(height, width, CV_8UC2, const_cast<uint8_t*>(data), stride);
  cv::cvtColor(yuyv, bgr, cv::COLOR_YUV2BGR_YUYV);
  return 0;
}

int mjpeg_to_bgr(const uint8_t* data, size_t bytes, cv::Mat& bgr) {
  if (!data || bytes == 0) return -EBADMSG;
  cv::Mat raw(1, static_cast<int>(bytes), CV_8UC1, const_cast<uint8_t*>(data));
  cv::Mat out = cv::imdecode(raw, cv::IMREAD_COLOR);
  if (out.empty()) return -EBADMSG;
  bgr = out;
  return 0;
}

}  // namespace rbx1::camera
