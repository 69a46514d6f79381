// control_client.hpp - the rbx1d control socket client: connect, send one request line, read the reply lines.
#pragma once
#include <sys/un.h>

#include <string>

#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::control {

// Default socket path (also the [daemon] socket default).
inline constexpr const char* kDefaultSocket = "/run/rbx1/rbx1d.sock";

// The address of a Unix socket at path; false when the path is empty or does not fit.
bool unix_address(const std::string& path, sockaddr_un& addr);

class Client {
 public:
  Client() = default;
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  // 0 or a negative errno; error says "PATH: reason".
  int connect(const std::string& socket_path, std::string& error);
  // Sends one request as a JSON line. 0 or a negative errno.
  int send(const daemon::Request& request);
  int send_line(const std::string& line);  // raw line (tests, tools); a newline is appended
  // Reads the next line (without newline). 0, -ECONNRESET at end of stream, or a negative errno.
  // timeout_ms < 0 waits forever.
  int read_line(std::string& line, int timeout_ms = -1);
  void close();

 private:
  int fd_ = -1;
  std::string buffer_;
};

// True for the reply's last line: {"result": ...} or {"error": ...}.
bool is_final(const nlohmann::json& line);

}  // namespace rbx1::control
