// server.hpp - the control socket: a Unix stream socket taking one JSON request per line, streaming replies.
#pragma once
#include <atomic>
#include <cstddef>
#include <string>

#include "reply.hpp"

namespace rbx1::daemon {

// Limits that keep one client from stalling the others (host/daemon/README.md, "Control protocol").
struct ServerLimits {
  size_t max_clients = 256;           // connections at once; one more makes the least recently active one leave
  size_t max_output = 64 * 1024;      // a client's unsent reply bytes; beyond, the client is disconnected
  int idle_timeout_ms = 60000;        // no request open and nothing received for this long: disconnected
  size_t requests_per_client = 4;     // a client's requests waiting for the dispatcher; beyond, it is not read
};

class Server {
 public:
  Server() = default;
  ~Server();
  // Binds path (replacing a stale socket file), chmods it to mode. 0 or a negative errno with error set.
  int open(const std::string& path, unsigned mode, std::string& error);
  void set_limits(const ServerLimits& limits) { limits_ = limits; }
  // Serves until stop(); returns 0. Estop requests are handed to handler on this thread as soon as they are read,
  // before anything else; every other request goes to handler on a dispatcher thread, in order of arrival (at most
  // requests_per_client of one client waiting). Writes never block (each client has its own bounded output buffer).
  int run(const Handler& handler);
  void stop();  // any thread, also a signal handler
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int listen_fd_ = -1;
  int wake_fd_ = -1;
  ServerLimits limits_;
  std::atomic<bool> stopping_{false};
};

}  // namespace rbx1::daemon
