// error_codes.hpp - every error code a reply can carry, with what it means, in one list that the CLI (its exit
// code), the console (its HTTP status), the Python client (its exceptions) and the README read.
#pragma once
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace rbx1::daemon {

// Request: the request itself was wrong (CLI exit 2, HTTP 400). Job: the arm could not do it now (CLI exit 1,
// HTTP 409). Access: the client may not (HTTP 401/403).
enum class ErrorClass { Request, Job, Access };

struct ErrorCode {
  const char* code;
  ErrorClass cls;
  const char* meaning;
};

const std::vector<ErrorCode>& error_codes();
const ErrorCode* find_error(std::string_view code);
// True for codes of the request itself (bad_json, bad_field, ...).
bool is_request_error(std::string_view code);
nlohmann::json error_codes_json();
std::string error_codes_markdown();

}  // namespace rbx1::daemon
