// server.cpp - poll() loop over the listening socket and its clients: line framing, length limit, per-client
// bounded output buffers with non-blocking writes, e-stops on the server thread and everything else on a
// dispatcher thread, idle timeout, room for every new connection.
#include "server.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <spdlog/spdlog.h>

#include "control_client.hpp"

namespace rbx1::daemon {

namespace {
constexpr size_t kReadChunk = 4096;
constexpr int kAcceptPerRound = 64;

int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void wake(int fd) {
  uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(fd, &one, sizeof one);
}

// One connection as the replies see it: they write from any thread (the server's, the job worker's) and never
// wait. What the socket does not take at once waits in `out` for the server thread to send when it can.
struct Connection {
  std::mutex mu;
  int fd = -1;         // -1 once closed: later reply lines are dropped
  int wake_fd = -1;    // the server's eventfd: output is waiting, or the connection must go
  size_t max_output = 0;
  std::string out;     // reply bytes the socket has not taken yet
  const char* drop = nullptr;  // why the server must close it: output overflowed, or the peer is gone
  int open_replies = 0;  // requests whose final line has not been written yet
  size_t queued = 0;     // requests waiting for the dispatcher thread

  // The replies' sink.
  void write(const std::string& line, bool final) {
    std::lock_guard lock(mu);
    if (final && open_replies > 0) --open_replies;
    if (fd < 0 || drop) return;
    std::string data = line + "\n";
    size_t off = 0;
    if (out.empty()) {
      ssize_t n = ::send(fd, data.data(), data.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n < 0 && errno != EAGAIN && errno != EINTR) {
        drop = "the peer is gone";
        wake(wake_fd);
        return;
      }
      off = n > 0 ? size_t(n) : 0;
    }
    if (off == data.size()) return;
    if (out.size() + data.size() - off > max_output) {
      drop = "its replies are not read";  // a client that does not read loses its connection, not others' time
      out.clear();
    } else {
      out.append(data, off);
    }
    wake(wake_fd);
  }

  // Sends what the socket takes of out (server thread). False when the peer is gone.
  bool flush() {
    std::lock_guard lock(mu);
    while (fd >= 0 && !out.empty()) {
      ssize_t n = ::send(fd, out.data(), out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n < 0) {
        if (errno == EINTR) continue;
        if (errno == EAGAIN) return true;
        drop = "the peer is gone";
        return false;
      }
      out.erase(0, size_t(n));
    }
    return true;
  }

  // Whether the peer is still there (the jog's dead-man rule): not once it closed or shut down its end, nor after
  // a failed send.
  bool present() {
    std::lock_guard lock(mu);
    if (fd < 0 || drop) return false;
    pollfd p{fd, POLLRDHUP, 0};
    return !(::poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR)));
  }

  // Reply bytes the peer has not taken yet.
  size_t backlog() {
    std::lock_guard lock(mu);
    return out.size();
  }

  void close() {
    std::lock_guard lock(mu);
    if (fd >= 0) ::close(fd);
    fd = -1;
    out.clear();
  }
};

// The server thread's side of a connection.
struct Client {
  std::shared_ptr<Connection> conn;
  uint64_t id = 0;
  std::string partial;             // bytes of a line not yet ended
  std::deque<std::string> lines;   // complete request lines not yet handled
  bool discarding = false;         // after an overlong line: drop bytes until the next newline
  bool eof = false;                // the peer shut its writing side: answer what it sent, then close
  int64_t last_active_ms = 0;
};

Reply::Sink sink_for(const std::shared_ptr<Connection>& conn) {
  return [conn](const std::string& line, bool final) { conn->write(line, final); };
}

void submit(Client& c, const Handler& handler, const std::string& line) {
  {
    std::lock_guard lock(c.conn->mu);
    ++c.conn->open_replies;
  }
  submit_line(handler, line, sink_for(c.conn), [conn = c.conn] { return conn->present(); },
              [conn = c.conn] { return conn->backlog(); });
}

// Runs every request but estop on its own thread: the server thread only moves bytes and answers e-stops, so it is
// idle in poll() the moment an estop arrives however busy the handler is with other clients' requests.
class Dispatcher {
 public:
  Dispatcher(const Handler& handler, int wake_fd, size_t per_client)
      : handler_(handler), wake_fd_(wake_fd), per_client_(per_client), thread_([this] { loop(); }) {}
  ~Dispatcher() {
    {
      std::lock_guard lock(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  void push(const std::shared_ptr<Connection>& conn, std::string line) {
    {
      std::lock_guard lock(conn->mu);
      ++conn->open_replies;
      ++conn->queued;
    }
    {
      std::lock_guard lock(mu_);
      items_.push_back({conn, std::move(line)});
    }
    cv_.notify_one();
  }

 private:
  struct Item {
    std::shared_ptr<Connection> conn;
    std::string line;
  };
  void loop() {
    for (;;) {
      Item item;
      {
        std::unique_lock lock(mu_);
        cv_.wait(lock, [this] { return stop_ || !items_.empty(); });
        if (stop_) return;
        item = std::move(items_.front());
        items_.pop_front();
      }
      submit_line(handler_, item.line, sink_for(item.conn), [conn = item.conn] { return conn->present(); },
                  [conn = item.conn] { return conn->backlog(); });
      bool resume;
      {
        std::lock_guard lock(item.conn->mu);
        resume = item.conn->queued-- == per_client_;
      }
      if (resume) wake(wake_fd_);  // the server reads that client again
    }
  }
  const Handler& handler_;
  int wake_fd_;
  size_t per_client_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Item> items_;
  bool stop_ = false;
  std::thread thread_;
};

// True for a line that is an estop request (parsed in full: only a well-formed request counts).
bool is_estop(const std::string& line) {
  if (line.find("estop") == std::string::npos) return false;
  Request r;
  Error e;
  return parse_request(line, r, e) && r.command == Command::Estop;
}

// Splits received bytes into lines; an overlong line is answered with line_too_long and skipped.
void take_bytes(Client& c, const Handler& handler, const char* data, size_t n) {
  for (size_t k = 0; k < n; ++k) {
    char ch = data[k];
    if (ch == '\n') {
      if (c.discarding) {
        c.discarding = false;
      } else {
        if (!c.partial.empty() && c.partial.back() == '\r') c.partial.pop_back();
        if (!c.partial.empty()) c.lines.push_back(std::move(c.partial));
      }
      c.partial.clear();
    } else if (!c.discarding) {
      c.partial.push_back(ch);
      if (c.partial.size() > kMaxRequestLine) {
        submit(c, handler, c.partial);  // parse_request answers line_too_long
        c.partial.clear();
        c.discarding = true;
      }
    }
  }
}

// One run(): the clients and the steps of a poll round (poll, read and send, accept, e-stops first, dispatch, close).
class ServeLoop {
 public:
  ServeLoop(const Handler& handler, int listen_fd, int wake_fd, const ServerLimits& limits)
      : handler_(handler), listen_fd_(listen_fd), wake_fd_(wake_fd), limits_(limits),
        dispatcher_(handler, wake_fd, limits.requests_per_client) {}
  ~ServeLoop() {
    for (auto& c : clients_) c.conn->close();  // replies still running write nowhere from now on
  }

  // One round: 0, or a negative errno when poll() fails.
  int round() {
    std::vector<pollfd> fds;
    if (int r = poll(fds); r <= 0) return r == -EINTR ? 0 : r;
    if (fds[0].revents & POLLIN) {
      uint64_t v;
      [[maybe_unused]] ssize_t n = ::read(wake_fd_, &v, sizeof v);
    }
    now_ = now_ms();
    serve(fds);
    if (fds[1].revents & POLLIN) accept_new();
    submit_estops();
    dispatch();
    close_finished();
    return 0;
  }

 private:
  // Polls the wake fd, the listening socket and every client; a client with lines left over from the last round
  // is served again at once. 1, or a negative errno.
  int poll(std::vector<pollfd>& fds) {
    now_ = now_ms();
    bool backlog = false;
    int timeout = 1000;
    fds.push_back({wake_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (auto& c : clients_) {
      short events = 0;
      size_t waiting;
      {
        std::lock_guard lock(c.conn->mu);
        if (!c.conn->out.empty()) events |= POLLOUT;
        if (c.conn->open_replies > 0) c.last_active_ms = now_;
        waiting = c.conn->queued;
      }
      // A client's backlog is its own brake: not read while its requests wait.
      if (c.lines.empty() && waiting < limits_.requests_per_client && !c.eof) events |= POLLIN;
      backlog |= !c.lines.empty() && waiting < limits_.requests_per_client;
      timeout = int(std::min<int64_t>(timeout, std::max<int64_t>(0, c.last_active_ms + limits_.idle_timeout_ms - now_)));
      fds.push_back({c.conn->fd, events, 0});
    }
    if (::poll(fds.data(), fds.size(), backlog ? 0 : timeout) >= 0) return 1;
    int e = errno;
    if (e != EINTR) spdlog::error("control: poll: {}", std::strerror(e));
    return -e;
  }

  // Reads from and sends to the clients that were polled (those accepted later were not).
  void serve(const std::vector<pollfd>& fds) {
    for (size_t i = 0; i + 2 < fds.size(); ++i) {
      short ev = fds[2 + i].revents;
      Client& c = clients_[i];
      if (ev & POLLOUT) c.conn->flush();
      if (ev & POLLIN) read_from(c);
      if (ev & (POLLHUP | POLLERR | POLLNVAL)) {
        std::lock_guard lock(c.conn->mu);
        c.conn->drop = "the peer is gone";
      }
    }
  }

  void read_from(Client& c) {
    char buf[kReadChunk];
    ssize_t n = ::recv(c.conn->fd, buf, sizeof buf, 0);
    if (n > 0) {
      c.last_active_ms = now_;
      take_bytes(c, handler_, buf, size_t(n));
    } else if (n == 0) {
      c.eof = true;
    } else if (errno != EAGAIN && errno != EINTR) {
      std::lock_guard lock(c.conn->mu);
      c.conn->drop = "the peer is gone";
    }
  }

  // New connections: every one gets in (beyond max_clients the least recently active one makes room), and is
  // read at once: a client such as `rbx1 estop` sends its request right after connecting.
  void accept_new() {
    for (int k = 0; k < kAcceptPerRound; ++k) {
      int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (fd < 0) break;
      if (clients_.size() >= limits_.max_clients) evict_one();
      Client c;
      c.conn = std::make_shared<Connection>();
      c.conn->fd = fd;
      c.conn->wake_fd = wake_fd_;
      c.conn->max_output = limits_.max_output;
      c.id = next_id_++;
      c.last_active_ms = now_;
      read_from(c);
      clients_.push_back(std::move(c));
    }
  }

  // Makes room for a new connection: the least recently active client leaves, one with nothing open first.
  void evict_one() {
    auto victim = clients_.end();
    bool victim_open = true;
    for (auto it = clients_.begin(); it != clients_.end(); ++it) {
      bool open = open_replies(*it) > 0 || !it->lines.empty();
      if (victim == clients_.end() || (victim_open && !open) ||
          (open == victim_open && it->last_active_ms < victim->last_active_ms)) {
        victim = it;
        victim_open = open;
      }
    }
    if (victim == clients_.end()) return;
    spdlog::info("control: client {} disconnected to make room (more than {} connections)", victim->id,
                 limits_.max_clients);
    victim->conn->write(error_reply({ErrorCode::Busy, "disconnected: more than " + std::to_string(limits_.max_clients) +
                                                          " control connections"}).dump(), false);
    victim->conn->close();
    clients_.erase(victim);
  }

  // An e-stop first, wherever it waits: on this thread, before any other request.
  void submit_estops() {
    for (auto& c : clients_) {
      for (auto it = c.lines.begin(); it != c.lines.end();) {
        if (is_estop(*it)) {
          std::string line = std::move(*it);
          it = c.lines.erase(it);
          submit(c, handler_, line);
        } else {
          ++it;
        }
      }
    }
  }

  // Then the others' requests to the dispatcher, a bounded number waiting per client.
  void dispatch() {
    for (auto& c : clients_)
      while (!c.lines.empty() && queued(c) < limits_.requests_per_client) {
        dispatcher_.push(c.conn, std::move(c.lines.front()));
        c.lines.pop_front();
      }
  }

  // Closes what must go: overflowed or vanished peers, finished half-closed ones, idle ones.
  void close_finished() {
    std::erase_if(clients_, [&](Client& c) {
      const char* drop;
      bool done;
      int open;
      {
        std::lock_guard lock(c.conn->mu);
        drop = c.conn->drop;
        open = c.conn->open_replies;
        done = c.eof && open == 0 && c.lines.empty() && c.conn->out.empty();
      }
      bool idle = open == 0 && c.lines.empty() && now_ - c.last_active_ms >= limits_.idle_timeout_ms;
      if (!drop && !done && !idle) return false;
      if (drop) spdlog::log(std::strcmp(drop, "the peer is gone") ? spdlog::level::warn : spdlog::level::debug,
                            "control: client {} disconnected: {}", c.id, drop);
      else if (idle) spdlog::info("control: client {} idle for {} ms: disconnected", c.id, limits_.idle_timeout_ms);
      c.conn->close();
      return true;
    });
  }

  static size_t queued(const Client& c) {
    std::lock_guard lock(c.conn->mu);
    return c.conn->queued;
  }
  static int open_replies(const Client& c) {
    std::lock_guard lock(c.conn->mu);
    return c.conn->open_replies;
  }

  const Handler& handler_;
  int listen_fd_, wake_fd_;
  const ServerLimits& limits_;
  std::vector<Client> clients_;  // before dispatcher_: the dispatcher (its thread) goes first
  Dispatcher dispatcher_;
  uint64_t next_id_ = 1;
  int64_t now_ = 0;
};
}  // namespace

Server::~Server() {
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    ::unlink(path_.c_str());
  }
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

int Server::open(const std::string& path, unsigned mode, std::string& error) {
  path_ = path;
  // Bound and listening under a temporary name, then renamed into place: a client never finds the path before
  // it accepts connections (a connect between bind() and listen() would be refused).
  std::string tmp = path + ".new";
  sockaddr_un addr, tmp_addr;
  if (!control::unix_address(path, addr) || !control::unix_address(tmp, tmp_addr)) {
    error = path + ": not a usable Unix socket path (empty or too long)";
    return -ENAMETOOLONG;
  }
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
  ::unlink(tmp.c_str());
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listen_fd_ < 0 || ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&tmp_addr), sizeof tmp_addr) < 0 ||
      ::chmod(tmp.c_str(), mode) < 0 || ::listen(listen_fd_, 128) < 0 || ::rename(tmp.c_str(), path.c_str()) < 0) {
    int e = errno;
    error = path + ": " + std::strerror(e);
    ::unlink(tmp.c_str());
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
  if (wake_fd_ >= 0) wake(wake_fd_);
}

int Server::run(const Handler& handler) {
  ServeLoop loop(handler, listen_fd_, wake_fd_, limits_);
  while (!stopping_)
    if (int r = loop.round(); r < 0) return r;
  return 0;
}

}  // namespace rbx1::daemon
