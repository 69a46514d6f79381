// request.cpp - request line parsing: every malformed line becomes an error value, never an exception.
#include "request.hpp"

namespace rbx1::daemon {

namespace {
struct CommandName {
  Command command;
  const char* name;
};
constexpr CommandName kCommands[] = {
    {Command::Status, "status"}, {Command::Scan, "scan"},   {Command::Pick, "pick"},
    {Command::Home, "home"},     {Command::Estop, "estop"}, {Command::ClearFault, "clear_fault"},
    {Command::Shutdown, "shutdown"},
    {Command::Jog, "jog"},       {Command::PoseSave, "pose_save"}, {Command::PlaceSave, "place_save"},
    {Command::Background, "background"}, {Command::Teach, "teach"},
    {Command::CalibrateWorkspace, "calibrate_workspace"},
    {Command::Sort, "sort"}, {Command::Clear, "clear"}, {Command::RecipeSave, "recipe_save"},
    {Command::History, "history"}, {Command::Pause, "pause"}, {Command::Resume, "resume"}, {Command::Cancel, "cancel"},
};

// A label or place: printable, short, no control characters (it ends up in events and logs).
bool valid_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}
}  // namespace

const char* command_name(Command c) {
  for (const auto& e : kCommands)
    if (e.command == c) return e.name;
  return "?";
}

bool parse_request(std::string_view line, Request& out, Error& error) {
  if (line.size() > kMaxRequestLine) {
    error = {"line_too_long", "request longer than " + std::to_string(kMaxRequestLine) + " bytes"};
    return false;
  }
  nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    error = {"bad_json", "request is not valid JSON"};
    return false;
  }
  if (!j.is_object()) {
    error = {"bad_request", "request must be a JSON object"};
    return false;
  }
  auto cmd = j.find("cmd");
  if (cmd == j.end()) {
    error = {"missing_field", "request has no \"cmd\""};
    return false;
  }
  if (!cmd->is_string()) {
    error = {"bad_field", "\"cmd\" must be a string"};
    return false;
  }
  const std::string& name = cmd->get_ref<const std::string&>();
  bool found = false;
  for (const auto& e : kCommands)
    if (name == e.name) {
      out = Request{};
      out.command = e.command;
      found = true;
    }
  if (!found) {
    std::string shown = name.size() > 40 ? name.substr(0, 40) + "..." : name;
    error = {"unknown_command", "unknown command \"" + shown + "\""};
    return false;
  }
  if (is_operator_command(out.command)) return parse_operator_fields(j, name, out, error);
  if (is_jobs_command(out.command)) return parse_jobs_fields(j, name, out, error);
  // Only pick takes arguments; anything else present is a mistake worth reporting.
  for (const auto& [key, value] : j.items()) {
    if (key == "cmd") continue;
    if (out.command == Command::Pick && (key == "name" || key == "place")) continue;
    error = {"bad_field", "unknown field \"" + key.substr(0, 40) + "\" for " + name};
    return false;
  }
  if (out.command == Command::Pick) {
    for (const char* field : {"name", "place"}) {
      auto f = j.find(field);
      if (f == j.end()) {
        error = {"missing_field", std::string("pick needs \"") + field + "\""};
        return false;
      }
      if (!f->is_string() || !valid_name(f->get<std::string>())) {
        error = {"bad_field", std::string("\"") + field + "\" must be a non-empty string of at most 64 printable characters"};
        return false;
      }
      (std::string_view(field) == "name" ? out.name : out.place) = f->get<std::string>();
    }
  }
  return true;
}

nlohmann::json request_json(const Request& r) {
  nlohmann::json j{{"cmd", command_name(r.command)}};
  if (r.command == Command::Pick) {
    j["name"] = r.name;
    j["place"] = r.place;
  }
  if (is_operator_command(r.command)) operator_fields_json(r, j);
  if (is_jobs_command(r.command)) jobs_fields_json(r, j);
  return j;
}

nlohmann::json error_reply(const Error& e) { return {{"error", {{"code", e.code}, {"message", e.message}}}}; }
nlohmann::json result_reply(nlohmann::json result) { return {{"result", std::move(result)}}; }

}  // namespace rbx1::daemon
