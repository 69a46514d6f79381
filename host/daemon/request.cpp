// request.cpp - request line parsing: every malformed line becomes an error value, never an exception. The fields
// of each command are checked as command_table.cpp declares them.
#include "request.hpp"

#include "command_table.hpp"

namespace rbx1::daemon {

bool parse_request(std::string_view line, Request& out, Error& error) {
  if (line.size() > kMaxRequestLine) {
    error = {ErrorCode::LineTooLong, "request longer than " + std::to_string(kMaxRequestLine) + " bytes"};
    return false;
  }
  nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    error = {ErrorCode::BadJson, "request is not valid JSON"};
    return false;
  }
  if (!j.is_object()) {
    error = {ErrorCode::BadRequest, "request must be a JSON object"};
    return false;
  }
  auto cmd = j.find("cmd");
  if (cmd == j.end()) {
    error = {ErrorCode::MissingField, "request has no \"cmd\""};
    return false;
  }
  if (!cmd->is_string()) {
    error = {ErrorCode::BadField, "\"cmd\" must be a string"};
    return false;
  }
  const std::string& name = cmd->get_ref<const std::string&>();
  const CommandSpec* spec = find_command(name);
  if (!spec) {
    std::string shown = name.size() > 40 ? name.substr(0, 40) + "..." : name;
    error = {ErrorCode::UnknownCommand, "unknown command \"" + shown + "\""};
    return false;
  }
  out = Request{};
  out.command = spec->command;
  return parse_fields(*spec, j, out, error);
}

nlohmann::json error_reply(const Error& e) { return {{"error", {{"code", e.code}, {"message", e.message}}}}; }
nlohmann::json result_reply(nlohmann::json result) { return {{"result", std::move(result)}}; }

}  // namespace rbx1::daemon
