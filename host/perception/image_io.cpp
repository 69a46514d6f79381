// image_io.cpp - image file reading with header checks, so corrupt or huge files fail with one clear line.
#include "image_io.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

uint32_t be32(const unsigned char* p) { return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | p[3]; }

// Width and height from a PNG or JPEG header (the formats the camera and the tools write); false if unknown.
bool header_size(const std::vector<unsigned char>& b, long long& w, long long& h) {
  if (b.size() >= 24 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G' && b[12] == 'I' && b[13] == 'H' &&
      b[14] == 'D' && b[15] == 'R') {
    w = be32(&b[16]);
    h = be32(&b[20]);
    return true;
  }
  if (b.size() >= 4 && b[0] == 0xFF && b[1] == 0xD8) {
    size_t i = 2;
    while (i + 9 < b.size()) {
      if (b[i] != 0xFF) return false;
      unsigned char m = b[i + 1];
      size_t len = (size_t(b[i + 2]) << 8) | b[i + 3];
      bool sof = (m >= 0xC0 && m <= 0xCF) && m != 0xC4 && m != 0xC8 && m != 0xCC;
      if (sof) {
        h = (static_cast<long long>(b[i + 5]) << 8) | b[i + 6];
        w = (static_cast<long long>(b[i + 7]) << 8) | b[i + 8];
        return true;
      }
      i += 2 + len;
    }
  }
  return false;
}

bool size_ok(long long w, long long h, std::string& error) {
  if (w <= 0 || h <= 0) {
    error = "image is empty (" + std::to_string(w) + "x" + std::to_string(h) + ")";
    return false;
  }
  if (w > kMaxImageSide || h > kMaxImageSide || w * h > kMaxImagePixels) {
    error = "image too large (" + std::to_string(w) + "x" + std::to_string(h) + "; limit " +
            std::to_string(kMaxImagePixels / 1'000'000) + " megapixels, " + std::to_string(kMaxImageSide) + " per side)";
    return false;
  }
  return true;
}

// A file cut short still decodes (libjpeg fills the rest with grey, libpng may stop after the last full row):
// a JPEG must have its end-of-image marker after the first scan, a PNG its IEND chunk at the end.
bool complete(const std::vector<unsigned char>& b) {
  if (b.size() >= 8 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G') {
    static const unsigned char iend[] = {'I', 'E', 'N', 'D'};
    size_t from = b.size() > 64 ? b.size() - 64 : 0;
    return std::search(b.begin() + long(from), b.end(), iend, iend + 4) != b.end();
  }
  if (b.size() >= 2 && b[0] == 0xFF && b[1] == 0xD8) {
    size_t i = 2, sos = 0;
    while (i + 3 < b.size()) {  // walk the marker segments up to the first scan
      if (b[i] != 0xFF) return false;
      if (b[i + 1] == 0xDA) {
        sos = i;
        break;
      }
      i += 2 + ((size_t(b[i + 2]) << 8) | b[i + 3]);
    }
    if (sos == 0) return false;
    for (size_t j = b.size() - 1; j > sos + 1; --j)  // entropy data stuffs 0xFF as FF 00: FF D9 is the end
      if (b[j] == 0xD9 && b[j - 1] == 0xFF) return true;
    return false;
  }
  return true;  // other formats: the decoder's own checks
}

// Significant bits of a 16-bit PNG: its sBIT chunk when present, else the smallest depth holding the data
// (a 10-bit sensor image stored in 16 bits uses 0..1023).
int significant_bits(const std::vector<unsigned char>& b, const cv::Mat& img) {
  if (b.size() >= 8 && b[0] == 0x89 && b[1] == 'P') {
    size_t i = 8;
    while (i + 12 <= b.size()) {
      size_t len = be32(&b[i]);
      if (std::memcmp(&b[i + 4], "sBIT", 4) == 0 && len >= 1 && i + 8 + len <= b.size()) {
        int bits = 0;
        for (size_t k = 0; k < len; ++k) bits = std::max(bits, int(b[i + 8 + k]));
        if (bits >= 1 && bits <= 16) return bits;
      }
      if (std::memcmp(&b[i + 4], "IDAT", 4) == 0) break;
      i += 12 + len;
    }
  }
  double mx = 0;
  cv::minMaxLoc(img.reshape(1), nullptr, &mx);
  int bits = 8;
  while (bits < 16 && mx > double((1 << bits) - 1)) ++bits;
  return bits;
}

}  // namespace

bool check_frame(const cv::Mat& frame, std::string& error) {
  if (frame.empty()) {
    error = "frame is empty";
    return false;
  }
  if (frame.channels() != 1 && frame.channels() != 3 && frame.channels() != 4) {
    error = "frame has " + std::to_string(frame.channels()) + " channels (need 1, 3 or 4)";
    return false;
  }
  return size_ok(frame.cols, frame.rows, error);
}

bool read_image(const std::string& path, cv::Mat& out, std::string& error) {
  std::error_code ec;
  auto st = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(st)) {
    error = path + ": is a folder, not an image file";
    return false;
  }
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
    error = path + ": not a regular file";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = path + ": cannot be read";
    return false;
  }
  in.seekg(0, std::ios::end);
  std::streamoff n = in.tellg();
  if (n <= 0) {
    error = path + ": file is empty or not a regular file";
    return false;
  }
  if (n > 512ll * 1024 * 1024) {
    error = path + ": file too large (" + std::to_string(n) + " bytes)";
    return false;
  }
  in.seekg(0);
  std::vector<unsigned char> bytes(static_cast<size_t>(n));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), n)) {
    error = path + ": read failed";
    return false;
  }
  long long w = 0, h = 0;
  std::string why;
  if (header_size(bytes, w, h) && !size_ok(w, h, why)) {
    error = path + ": " + why;
    return false;
  }
  if (!complete(bytes)) {
    error = path + ": not a readable image (truncated or corrupt: no end marker)";
    return false;
  }
  cv::Mat img;
  // Codec libraries (libpng, libjpeg) print their own complaints on stderr; the caller's one line says it all.
  int saved = ::dup(2), devnull = ::open("/dev/null", O_WRONLY);
  if (saved >= 0 && devnull >= 0) ::dup2(devnull, 2);
  try {
    img = cv::imdecode(bytes, cv::IMREAD_ANYCOLOR | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception&) {
    img.release();
  }
  if (saved >= 0) ::dup2(saved, 2), ::close(saved);
  if (devnull >= 0) ::close(devnull);
  if (img.empty()) {
    error = path + ": not a readable image (corrupt or unknown format)";
    return false;
  }
  if (!check_frame(img, why)) {
    error = path + ": " + why;
    return false;
  }
  if (img.depth() == CV_16U) {
    // Keep the contrast of high-bit-depth data: scale its significant range, not the full 16 bits, to 8 bits.
    int bits = significant_bits(bytes, img);
    cv::Mat t;
    img.convertTo(t, CV_8U, 255.0 / double((1 << bits) - 1));
    img = t;
  }
  out = img;
  return true;
}

cv::Mat to_gray8(const cv::Mat& frame) {
  cv::Mat g;
  if (frame.channels() == 3) cv::cvtColor(frame, g, cv::COLOR_BGR2GRAY);
  else if (frame.channels() == 4) cv::cvtColor(frame, g, cv::COLOR_BGRA2GRAY);
  else g = frame;
  if (g.depth() != CV_8U) {
    double scale = g.depth() == CV_16U ? 1.0 / 257.0 : (g.depth() == CV_32F || g.depth() == CV_64F ? 255.0 : 1.0);
    cv::Mat t;
    g.convertTo(t, CV_8U, scale);
    g = t;
  }
  return g;
}

}  // namespace rbx1::vision
