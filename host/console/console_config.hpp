// console_config.hpp - the [console] table: where the web console listens, its token, the live view's pace.
#pragma once
#include <string>

#include "config.hpp"

namespace rbx1::console {

inline constexpr const char* kDefaultBind = "127.0.0.1:8080";

struct ConsoleConfig {
  bool enabled = true;
  std::string bind = kDefaultBind;  // "HOST:PORT"; HOST an IPv4 address, "localhost" or "[IPv6]"; PORT 0 = any free
  std::string token;                // "" = none; required when bind is not a loopback address
  double live_fps = 10;             // live view: frames per second grabbed and encoded (shared by every viewer)
  int jpeg_quality = 80;            // live view and scan image JPEG quality
  // Parsed from bind.
  std::string host = "127.0.0.1";
  int port = 8080;
  bool loopback = true;
};

// "HOST:PORT" -> host (without brackets), port; false + error for anything else.
bool parse_bind(const std::string& bind, std::string& host, int& port, std::string& error);
// 127.0.0.0/8, ::1 and "localhost".
bool is_loopback_host(const std::string& host);

// Reads the [console] table; errors name the key (console.token when a non-loopback bind has no token).
void parse_console_config(config::Section console, ConsoleConfig& out);
// rbx1d --console BIND: replaces the file's bind, with the same checks (errors name "--console" or console.token).
void override_console_bind(const std::string& bind, ConsoleConfig& out, config::Errors& errors);

}  // namespace rbx1::console
