// socket_source.hpp - frames from a frame server on a Unix socket (device = "unix:PATH"), e.g. rbx1-world.
#pragma once
#include <string>

#include "frame_source.hpp"

namespace rbx1::camera {

// The wire (one request, one reply, on a stream socket; the connection stays open between frames):
//   client: "frame\n"
//   server: "frame WIDTH HEIGHT\n" followed by WIDTH*HEIGHT*3 bytes of BGR, row by row
//           or "error TEXT\n"
// A dropped connection is re-opened on the next read.
class SocketSource : public FrameSource {
 public:
  explicit SocketSource(std::string path) : path_(std::move(path)) {}
  ~SocketSource() override;
  int open(std::string& error);  // connects once, so a wrong path fails at start-up; 0 or -errno
  int read(cv::Mat& bgr) override;
  std::string describe() const override;
  bool moves_with_arm() const override { return true; }

 private:
  int connect_socket(std::string& error);
  std::string path_;
  int fd_ = -1;
  int width_ = 0, height_ = 0;
};

constexpr const char* kSocketPrefix = "unix:";

}  // namespace rbx1::camera
