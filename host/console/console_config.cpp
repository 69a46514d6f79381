// console_config.cpp - reads and checks the [console] table: the listener's address, its token, the live view.
#include "console_config.hpp"

#include <arpa/inet.h>

namespace rbx1::console {

bool parse_bind(const std::string& bind, std::string& host, int& port, std::string& error) {
  size_t colon = bind.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == bind.size()) {
    error = "must be \"HOST:PORT\" (e.g. \"127.0.0.1:8080\"), got \"" + bind + "\"";
    return false;
  }
  host = bind.substr(0, colon);
  std::string port_text = bind.substr(colon + 1);
  bool bracketed = host.size() >= 2 && host.front() == '[' && host.back() == ']';
  if (bracketed) host = host.substr(1, host.size() - 2);
  unsigned char buf[16];
  bool v4 = !bracketed && inet_pton(AF_INET, host.c_str(), buf) == 1;
  bool v6 = bracketed && inet_pton(AF_INET6, host.c_str(), buf) == 1;
  if (!v4 && !v6 && !(host == "localhost" && !bracketed)) {
    error = "host must be an IPv4 address, \"localhost\" or a bracketed IPv6 address, got \"" + host + "\"";
    return false;
  }
  if (port_text.empty() || port_text.size() > 5 || port_text.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port_text) > 65535) {
    error = "port must be a number 0..65535, got \"" + port_text + "\"";
    return false;
  }
  port = std::stoi(port_text);
  return true;
}

bool is_loopback_host(const std::string& host) {
  if (host == "localhost" || host == "::1") return true;
  in_addr a{};
  return inet_pton(AF_INET, host.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

namespace {
// The bind address and the token rule; errors name bind_key and "console.token".
void set_bind(const std::string& bind, const std::string& bind_key, ConsoleConfig& out, config::Errors& errors) {
  out.bind = bind;
  std::string error;
  if (!parse_bind(out.bind, out.host, out.port, error)) {
    errors.add(bind_key, error);
    return;
  }
  out.loopback = is_loopback_host(out.host);
  if (out.enabled && !out.loopback && out.token.empty())
    errors.add("console.token", "must be set when the console listens beyond loopback (" + bind_key + " \"" + out.bind +
                                    "\"): anybody on that network could move the arm");
}
}  // namespace

void override_console_bind(const std::string& bind, ConsoleConfig& out, config::Errors& errors) {
  set_bind(bind, "--console", out, errors);
}

void parse_console_config(config::Section s, ConsoleConfig& out) {
  out.enabled = s.boolean("enabled", out.enabled);
  std::string bind = s.string("bind", out.bind);
  out.token = s.string("token", out.token);
  bool printable = true;
  for (unsigned char c : out.token) printable = printable && c > 0x20 && c < 0x7f;
  if (!out.token.empty() && (out.token.size() < 16 || out.token.size() > 200 || !printable))
    s.errors().add(s.path() + ".token", "must be 16..200 printable characters without spaces (e.g. from `openssl rand -hex 16`)");
  set_bind(bind, s.path() + ".bind", out, s.errors());
  out.live_fps = s.number("live_fps", out.live_fps, 0.5, 60);
  out.jpeg_quality = int(s.integer("jpeg_quality", out.jpeg_quality, 10, 100));
  s.reject_unknown();
}

}  // namespace rbx1::console
