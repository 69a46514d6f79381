// error_codes.cpp - the list of error codes (GRBL keeps its codes in one CSV that host tools read; this is ours).
#include "error_codes.hpp"

namespace rbx1::daemon {

namespace {
using C = ErrorClass;
// Never destroyed: a detached thread's reply may still name its code while the process exits.
const std::vector<ErrorInfo>& kCodes = *new std::vector<ErrorInfo>{
#define RBX1_ERROR_ROW(name, code, cls, meaning) {ErrorCode::name, code, C::cls, meaning},
    RBX1_ERROR_CODES(RBX1_ERROR_ROW)
#undef RBX1_ERROR_ROW
};

const char* class_name(ErrorClass c) {
  switch (c) {
    case C::Request: return "request";
    case C::Job: return "job";
    case C::Access: return "access";
  }
  return "?";
}
}  // namespace

const std::vector<ErrorInfo>& error_codes() { return kCodes; }

const ErrorInfo& error_info(ErrorCode id) { return kCodes[size_t(id)]; }  // rows in the enum's order

const char* code_name(ErrorCode id) { return error_info(id).code; }

const ErrorInfo* find_error(std::string_view code) {
  for (const auto& e : kCodes)
    if (code == e.code) return &e;
  return nullptr;
}

bool is_request_error(std::string_view code) {
  const ErrorInfo* e = find_error(code);
  return e && e->cls == C::Request;
}

nlohmann::json error_codes_json() {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& e : kCodes) out.push_back({{"code", e.code}, {"class", class_name(e.cls)}, {"meaning", e.meaning}});
  return out;
}

std::string error_codes_markdown() {
  std::string md = "| error code | class | meaning |\n|---|---|---|\n";
  for (const auto& e : kCodes) md += std::string("| `") + e.code + "` | " + class_name(e.cls) + " | " + e.meaning + " |\n";
  return md;
}

}  // namespace rbx1::daemon
