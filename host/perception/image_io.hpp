// image_io.hpp - reads an image file defensively: size limits checked from the header before decoding.
#pragma once
#include <string>

#include <opencv2/core.hpp>

namespace rbx1::vision {

inline constexpr long long kMaxImagePixels = 40'000'000;  // about 7300 x 5500; larger frames are refused
inline constexpr int kMaxImageSide = 16384;

// Loads PATH as 8-bit BGR (colour) or gray. false + error "PATH: reason" on any problem; never throws.
bool read_image(const std::string& path, cv::Mat& out, std::string& error);
// Checks a frame already in memory against the same limits. false + error "reason".
bool check_frame(const cv::Mat& frame, std::string& error);
// Converts a BGR, BGRA or gray frame of any depth to 8-bit gray.
cv::Mat to_gray8(const cv::Mat& frame);

}  // namespace rbx1::vision
