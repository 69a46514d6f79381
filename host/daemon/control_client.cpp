// control_client.cpp - Unix socket client of rbx1d: line-framed JSON over a stream socket.
#include "control_client.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace rbx1::control {

bool unix_address(const std::string& path, sockaddr_un& addr) {
  addr = sockaddr_un{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) return false;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return true;
}

Client::~Client() { close(); }

void Client::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  buffer_.clear();
}

int Client::connect(const std::string& socket_path, std::string& error) {
  close();
  sockaddr_un addr;
  if (!unix_address(socket_path, addr)) {
    error = socket_path + ": path too long for a Unix socket";
    return -ENAMETOOLONG;
  }
  fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) {
    int e = errno;
    error = socket_path + ": " + std::strerror(e);
    return -e;
  }
  if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) < 0) {
    int e = errno;
    error = socket_path + ": " + std::strerror(e) + (e == ENOENT || e == ECONNREFUSED ? " (is rbx1d running?)" : "");
    close();
    return -e;
  }
  return 0;
}

int Client::send_line(const std::string& line) {
  if (fd_ < 0) return -ENOTCONN;
  std::string data = line + "\n";
  size_t off = 0;
  while (off < data.size()) {
    ssize_t n = ::send(fd_, data.data() + off, data.size() - off, MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      return -errno;
    }
    off += size_t(n);
  }
  return 0;
}

int Client::send(const daemon::Request& request) { return send_line(daemon::request_json(request).dump()); }

int Client::read_line(std::string& line, int timeout_ms) {
  if (fd_ < 0) return -ENOTCONN;
  for (;;) {
    size_t nl = buffer_.find('\n');
    if (nl != std::string::npos) {
      line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      return 0;
    }
    pollfd p{fd_, POLLIN, 0};
    int r = ::poll(&p, 1, timeout_ms);
    if (r < 0) {
      if (errno == EINTR) continue;
      return -errno;
    }
    if (r == 0) return -ETIMEDOUT;
    char buf[4096];
    ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      return -errno;
    }
    if (n == 0) return -ECONNRESET;
    buffer_.append(buf, size_t(n));
  }
}

bool is_final(const nlohmann::json& line) {
  return line.is_object() && (line.contains("result") || line.contains("error"));
}

}  // namespace rbx1::control
