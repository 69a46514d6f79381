// socket_source_test.cpp - SocketSource against a frame server thread: frames, reconnects, bad headers, a missing server.
#include <atomic>
#include <cstring>
#include <filesystem>
#include <sys/socket.h>
#include <sys/un.h>
#include <thread>
#include <unistd.h>

#include <gtest/gtest.h>

#include "frame_source.hpp"

namespace {

// A frame server thread on one Unix socket: good frames, a bad header, or one frame per connection.
class FrameServer {
 public:
  enum class Mode { Good, BadHeader, CloseAfterOne };
  FrameServer(std::string path, Mode mode) : path_(std::move(path)), mode_(mode) {
    ::unlink(path_.c_str());
    listen_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strcpy(a.sun_path, path_.c_str());
    EXPECT_EQ(::bind(listen_, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
    EXPECT_EQ(::listen(listen_, 4), 0);
    thread_ = std::thread([this] { run(); });
  }
  ~FrameServer() {
    stop_ = true;
    ::shutdown(listen_, SHUT_RDWR);
    thread_.join();
    ::close(listen_);
    ::unlink(path_.c_str());
  }
  std::atomic<int> served{0}, connections{0};

 private:
  void run() {
    while (!stop_) {
      int c = ::accept(listen_, nullptr, nullptr);
      if (c < 0) return;
      connections++;
      char buf[6];
      while (!stop_ && ::recv(c, buf, 6, MSG_WAITALL) == 6) {
        if (mode_ == Mode::BadHeader) {
          ::send(c, "picture 1 1\n", 12, MSG_NOSIGNAL);
          continue;
        }
        const int w = 32, h = 16;
        std::string msg = "frame 32 16\n";
        std::string body(size_t(w) * h * 3, '\0');
        for (int i = 0; i < w * h; ++i) body[size_t(i) * 3 + 2] = char(served.load() + 1);  // red = frame number
        msg += body;
        ::send(c, msg.data(), msg.size(), MSG_NOSIGNAL);
        served++;
        if (mode_ == Mode::CloseAfterOne) break;
      }
      ::close(c);
    }
  }
  std::string path_;
  Mode mode_;
  int listen_ = -1;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

std::string socket_path(const char* name) {
  return (std::filesystem::temp_directory_path() / (std::string("rbx1-cam-") + name + "-" +
                                                    std::to_string(::getpid()) + ".sock")).string();
}

}  // namespace

TEST(SocketSource, ServesFramesOverOneConnection) {
  std::string path = socket_path("good");
  FrameServer server(path, FrameServer::Mode::Good);
  rbx1::camera::CameraConfig cfg;
  cfg.device = "unix:" + path;
  std::string error;
  auto src = rbx1::camera::open_source(cfg, error);
  ASSERT_TRUE(src) << error;
  for (int i = 1; i <= 3; ++i) {
    cv::Mat m;
    ASSERT_EQ(src->read(m), 0);
    ASSERT_EQ(m.cols, 32);
    ASSERT_EQ(m.rows, 16);
    EXPECT_EQ(m.at<cv::Vec3b>(15, 31), cv::Vec3b(0, 0, uchar(i)));
  }
  EXPECT_EQ(server.connections.load(), 1);
  EXPECT_EQ(src->describe(), "socket unix:" + path + " (32x16)");
}

TEST(SocketSource, ReconnectsWhenTheServerClosed) {
  std::string path = socket_path("close");
  FrameServer server(path, FrameServer::Mode::CloseAfterOne);
  rbx1::camera::CameraConfig cfg;
  cfg.device = "unix:" + path;
  std::string error;
  auto src = rbx1::camera::open_source(cfg, error);
  ASSERT_TRUE(src) << error;
  cv::Mat m;
  ASSERT_EQ(src->read(m), 0);
  ASSERT_EQ(src->read(m), 0);
  EXPECT_EQ(m.at<cv::Vec3b>(0, 0)[2], 2);
  EXPECT_EQ(server.connections.load(), 2);
}

TEST(SocketSource, MissingServerAndBadHeaderAreClearErrors) {
  std::string path = socket_path("absent");
  ::unlink(path.c_str());
  rbx1::camera::CameraConfig cfg;
  cfg.device = "unix:" + path;
  std::string error;
  EXPECT_FALSE(rbx1::camera::open_source(cfg, error));
  EXPECT_EQ(error, "unix:" + path + ": No such file or directory (is the frame server running?)");

  std::string bad = socket_path("bad");
  FrameServer server(bad, FrameServer::Mode::BadHeader);
  cfg.device = "unix:" + bad;
  auto src = rbx1::camera::open_source(cfg, error);
  ASSERT_TRUE(src) << error;
  cv::Mat m;
  EXPECT_EQ(src->read(m), -EBADMSG);
}
