// convert.hpp - camera buffers to BGR images, kept apart from the device so tests feed synthetic buffers.
#pragma once
#include <cstddef>
#include <cstdint>

#include <opencv2/core.hpp>

namespace rbx1::camera {

// Packed YUYV 4:2:2 (V4L2_PIX_FMT_YUYV) of width x height with bytesperline stride (0: width*2) -> BGR.
// -EINVAL when the buffer is too short or the size is odd.
int yuyv_to_bgr(const uint8_t* data, size_t bytes, int width, int height, size_t bytesperline, cv::Mat& bgr);

// One MJPEG frame (a JPEG image) -> BGR. -EBADMSG when it does not decode.
int mjpeg_to_bgr(const uint8_t* data, size_t bytes, cv::Mat& bgr);

}  // namespace rbx1::camera
