// server.cpp - poll() loop over the listening socket and its clients; line framing, length limit, error replies.
#include "server.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <vector>

#include <spdlog/spdlog.h>

namespace rbx1::daemon {

namespace {
constexpr size_t kMaxClients = 32;

struct Client {
  std::shared_ptr<int> fd;  // shared with the replies that may outlive the connection's reading side
  std::string buffer;
  bool discarding = false;  // after an overlong line: drop bytes until the next newline
};

void close_fd(int* fd) {
  if (*fd >= 0) ::close(*fd);
  delete fd;
}
}  // namespace

std::string iso_now() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  tm t{};
  gmtime_r(&ts.tv_sec, &t);
  char buf[40];
  size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &t);
  std::snprintf(buf + n, sizeof buf - n, ".%03ldZ", ts.tv_nsec / 1000000);
  return buf;
}

Reply::Reply(std::shared_ptr<int> fd, Command command)
    : fd_(std::move(fd)), command_(command), start_(std::chrono::steady_clock::now()) {}

double Reply::elapsed_ms() const {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
}

void Reply::write_line(const nlohmann::json& j) {
  if (!log_tag_.empty())
    spdlog::info("{}: {}", log_tag_, j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  if (!fd_ || *fd_ < 0) return;
  // Replace invalid UTF-8 rather than throw: a file name or label must never kill the daemon.
  std::string data = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
  size_t off = 0;
  while (off < data.size()) {
    ssize_t n = ::send(*fd_, data.data() + off, data.size() - off, MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN) {  // slow reader: wait a little for room, never forever
        pollfd p{*fd_, POLLOUT, 0};
        if (::poll(&p, 1, 1000) > 0) continue;
      }
      return;  // client gone: the job goes on, its events are dropped
    }
    off += size_t(n);
  }
}

void Reply::event(const std::string& name, nlohmann::json fields) {
  std::lock_guard lock(mutex_);
  if (finished_) return;
  nlohmann::json j{{"ts", iso_now()}, {"t_ms", std::round(elapsed_ms() * 10) / 10}, {"event", name}};
  if (fields.is_object())
    for (auto& [k, v] : fields.items()) j[k] = v;
  write_line(j);
}

void Reply::result(nlohmann::json result) {
  std::lock_guard lock(mutex_);
  if (finished_.exchange(true)) return;
  write_line(result_reply(std::move(result)));
}

void Reply::error(const std::string& code, const std::string& message) {
  std::lock_guard lock(mutex_);
  if (finished_.exchange(true)) return;
  write_line(error_reply({code, message}));
}

Server::~Server() {
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    ::unlink(path_.c_str());
  }
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

int Server::open(const std::string& path, unsigned mode, std::string& error) {
  path_ = path;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) {
    error = path + ": not a usable Unix socket path (empty or too long)";
    return -ENAMETOOLONG;
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      error = path + ": exists and is not a socket";
      return -EEXIST;
    }
    // A live daemon answers a connect; a stale file from a crash does not and is replaced.
    int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    bool live = probe >= 0 && ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    if (probe >= 0) ::close(probe);
    if (live) {
      error = path + ": another rbx1d is listening there";
      return -EADDRINUSE;
    }
    ::unlink(path.c_str());
  }
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listen_fd_ < 0 || ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0 ||
      ::chmod(path.c_str(), mode) < 0 || ::listen(listen_fd_, 16) < 0) {
    int e = errno;
    error = path + ": " + std::strerror(e);
    return -e;
  }
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake_fd_ < 0) {
    int e = errno;
    error = std::string("eventfd: ") + std::strerror(e);
    return -e;
  }
  return 0;
}

void Server::stop() {
  stopping_ = true;
  if (wake_fd_ >= 0) {
    uint64_t one = 1;
    [[maybe_unused]] ssize_t n = ::write(wake_fd_, &one, sizeof one);
  }
}

int Server::run(const Handler& handler) {
  std::vector<Client> clients;
  auto handle_line = [&](Client& c, const std::string& line) {
    Request request;
    Error err;
    if (!parse_request(line, request, err)) {
      spdlog::debug("control: rejected request: {}: {}", err.code, err.message);
      Reply(c.fd, Command::Status).error(err.code, err.message);
      return;
    }
    spdlog::info("control: request {}", request_json(request).dump());
    handler(request, std::make_shared<Reply>(c.fd, request.command));
  };
  while (!stopping_) {
    std::vector<pollfd> fds;
    fds.push_back({wake_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (auto& c : clients) fds.push_back({*c.fd, POLLIN, 0});
    int r = ::poll(fds.data(), fds.size(), -1);
    if (r < 0) {
      if (errno == EINTR) continue;
      spdlog::error("control: poll: {}", std::strerror(errno));
      return -errno;
    }
    const size_t polled = clients.size();  // clients accepted below were not in this poll
    if (fds[1].revents & POLLIN) {
      int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (fd >= 0) {
        auto shared = std::shared_ptr<int>(new int(fd), close_fd);
        if (clients.size() >= kMaxClients) {
          Reply(shared, Command::Status).error("busy", "too many control connections");
        } else {
          clients.push_back({shared, {}, false});
        }
      }
    }
    for (size_t i = 0; i < polled; ++i) {
      short ev = fds[2 + i].revents;
      if (!ev) continue;
      Client& c = clients[i];
      bool closed = false;
      if (ev & POLLIN) {
        char buf[4096];
        ssize_t n = ::recv(*c.fd, buf, sizeof buf, 0);
        if (n <= 0 && !(n < 0 && (errno == EAGAIN || errno == EINTR))) closed = true;
        for (ssize_t k = 0; k < n; ++k) {
          char ch = buf[k];
          if (ch == '\n') {
            if (c.discarding) {
              c.discarding = false;
            } else {
              if (!c.buffer.empty() && c.buffer.back() == '\r') c.buffer.pop_back();
              if (!c.buffer.empty()) handle_line(c, c.buffer);
            }
            c.buffer.clear();
          } else if (!c.discarding) {
            c.buffer.push_back(ch);
            if (c.buffer.size() > kMaxRequestLine) {
              Reply(c.fd, Command::Status)
                  .error("line_too_long", "request longer than " + std::to_string(kMaxRequestLine) + " bytes");
              c.buffer.clear();
              c.discarding = true;
            }
          }
        }
      } else if (ev & (POLLHUP | POLLERR | POLLNVAL)) {
        closed = true;
      }
      if (closed) c.fd.reset();  // replies still running keep the fd open until they finish
    }
    std::erase_if(clients, [](const Client& c) { return !c.fd; });
    if (fds[0].revents & POLLIN) {
      uint64_t v;
      [[maybe_unused]] ssize_t n = ::read(wake_fd_, &v, sizeof v);
    }
  }
  return 0;
}

}  // namespace rbx1::daemon
