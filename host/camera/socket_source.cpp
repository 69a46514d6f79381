// socket_source.cpp - SocketSource: "frame\n" out, a header line and the BGR bytes back, with a read timeout.
#include "socket_source.hpp"

#include <cerrno>
#include <cstring>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

namespace rbx1::camera {

namespace {
constexpr int kTimeoutMs = 30000;  // a frame server that does not answer within this is stalled (a
                                   // simulated one renders on a loaded machine: seconds)

// Reads exactly n bytes; 0 or -errno (-ETIMEDOUT, -ECONNRESET on EOF).
int read_exact(int fd, char* p, size_t n) {
  while (n > 0) {
    pollfd pfd{fd, POLLIN, 0};
    int r = poll(&pfd, 1, kTimeoutMs);
    if (r == 0) return -ETIMEDOUT;
    if (r < 0) {
      if (errno == EINTR) continue;
      return -errno;
    }
    ssize_t k = ::read(fd, p, n);
    if (k == 0) return -ECONNRESET;
    if (k < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return -errno;
    }
    p += k;
    n -= size_t(k);
  }
  return 0;
}

int read_line(int fd, std::string& line) {
  line.clear();
  char c;
  while (line.size() < 256) {
    if (int r = read_exact(fd, &c, 1); r < 0) return r;
    if (c == '\n') return 0;
    line += c;
  }
  return -EBADMSG;
}
}  // namespace

SocketSource::~SocketSource() {
  if (fd_ >= 0) ::close(fd_);
}

int SocketSource::connect_socket(std::string& error) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path_.size() >= sizeof(addr.sun_path)) {
    error = kSocketPrefix + path_ + ": path too long for a Unix socket";
    return -ENAMETOOLONG;
  }
  std::memcpy(addr.sun_path, path_.c_str(), path_.size() + 1);
  int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    int e = errno;
    error = kSocketPrefix + path_ + ": " + std::strerror(e);
    return -e;
  }
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    int e = errno;
    ::close(fd);
    error = kSocketPrefix + path_ + ": " + std::strerror(e) + " (is the frame server running?)";
    return -e;
  }
  fd_ = fd;
  return 0;
}

int SocketSource::open(std::string& error) { return connect_socket(error); }

int SocketSource::read(cv::Mat& bgr) {
  std::string error;
  // One reconnect per read: the server may have restarted between frames.
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (fd_ < 0 && connect_socket(error) < 0) {
      spdlog::error("{}", error);
      return -ECONNREFUSED;
    }
    static const char kRequest[] = "frame\n";
    int r = 0;
    if (::send(fd_, kRequest, sizeof(kRequest) - 1, MSG_NOSIGNAL) != ssize_t(sizeof(kRequest) - 1)) r = -errno;
    std::string header;
    if (r == 0) r = read_line(fd_, header);
    if (r == -EPIPE || r == -ECONNRESET) {
      ::close(fd_);
      fd_ = -1;
      continue;
    }
    if (r < 0) {
      spdlog::error("{}{}: frame request failed ({})", kSocketPrefix, path_, std::strerror(-r));
      ::close(fd_);
      fd_ = -1;
      return r;
    }
    int w = 0, h = 0;
    char word[16] = {};
    if (std::sscanf(header.c_str(), "%15s %d %d", word, &w, &h) != 3 || std::strcmp(word, "frame") != 0 || w < 16 ||
        h < 16 || w > 7680 || h > 4320) {
      spdlog::error("{}{}: bad frame header \"{}\"", kSocketPrefix, path_, header);
      ::close(fd_);  // the stream position is lost: start over on the next read
      fd_ = -1;
      return -EBADMSG;
    }
    bgr.create(h, w, CV_8UC3);
    r = read_exact(fd_, reinterpret_cast<char*>(bgr.data), size_t(w) * size_t(h) * 3);
    if (r < 0) {
      spdlog::error("{}{}: frame body failed ({})", kSocketPrefix, path_, std::strerror(-r));
      ::close(fd_);
      fd_ = -1;
      return r;
    }
    width_ = w;
    height_ = h;
    return 0;
  }
  spdlog::error("{}{}: the frame server closed the connection twice", kSocketPrefix, path_);
  return -ECONNRESET;
}

std::string SocketSource::describe() const {
  std::string s = std::string("socket ") + kSocketPrefix + path_;
  if (width_) s += " (" + std::to_string(width_) + "x" + std::to_string(height_) + ")";
  return s;
}

}  // namespace rbx1::camera
