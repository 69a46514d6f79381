// request.hpp - the control socket's request lines: parsing and validation into a typed Request, or an error reply.
#pragma once
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace rbx1::daemon {

// Longest request line accepted (bytes, newline excluded); longer lines get error "line_too_long".
inline constexpr size_t kMaxRequestLine = 4096;

enum class Command { Status, Scan, Pick, Home, Estop, ClearFault, Shutdown };

struct Request {
  Command command = Command::Status;
  std::string name;   // pick: the object's library label
  std::string place;  // pick: a place name from [arm] places
};

// An error reply: {"error": {"code": code, "message": message}}. Codes are stable strings clients test.
struct Error {
  std::string code;
  std::string message;
};

const char* command_name(Command c);
// One request line (without its newline) -> Request, or an Error (bad_json, bad_request, unknown_command,
// missing_field, bad_field). Never throws.
bool parse_request(std::string_view line, Request& out, Error& error);
// The request as a JSON line (what the client sends).
nlohmann::json request_json(const Request& r);

// Reply lines.
nlohmann::json error_reply(const Error& e);
nlohmann::json result_reply(nlohmann::json result);

}  // namespace rbx1::daemon
