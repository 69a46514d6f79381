// jobs_request.cpp - the cell jobs' request fields (sort, clear, recipe_save, history, pause, resume, cancel):
// each field checked for type and range, every mistake an error value (shared with the client).
#include <set>

#include "request.hpp"

namespace rbx1::daemon {

namespace {

const std::set<std::string>& allowed(Command c) {
  static const std::set<std::string> sort{"recipe", "max_picks"}, clear{"place", "max_picks"},
      save{"name", "recipe"}, history{"limit", "since", "job", "format"}, none{};
  switch (c) {
    case Command::Sort: return sort;
    case Command::Clear: return clear;
    case Command::RecipeSave: return save;
    case Command::History: return history;
    default: return none;
  }
}

bool bad(Error& error, const std::string& code, const std::string& message) {
  error = {code, message};
  return false;
}

bool printable(const std::string& s, size_t max) {
  if (s.empty() || s.size() > max) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}

bool string_field(const nlohmann::json& j, const char* key, size_t max, std::string& out, Error& error) {
  const auto& f = j[key];
  if (!f.is_string() || !printable(f.get<std::string>(), max))
    return bad(error, "bad_field", std::string("\"") + key + "\" must be a non-empty string of at most " +
                                       std::to_string(max) + " printable characters");
  out = f.get<std::string>();
  return true;
}

bool int_field(const nlohmann::json& j, const char* key, int64_t lo, int64_t hi, int64_t& out, Error& error) {
  const auto& f = j[key];
  if (!f.is_number_integer() || f.get<int64_t>() < lo || f.get<int64_t>() > hi)
    return bad(error, "bad_field", std::string("\"") + key + "\" must be an integer in " + std::to_string(lo) + ".." +
                                       std::to_string(hi));
  out = f.get<int64_t>();
  return true;
}

// A recipe: a saved recipe's name, or an object of class -> place (checked in full when the job runs).
bool recipe_field(const nlohmann::json& j, Request& out, Error& error, bool name_allowed) {
  const auto& f = j["recipe"];
  if (name_allowed && f.is_string()) {
    std::string name;
    if (!string_field(j, "recipe", 64, name, error)) return false;
    out.recipe = name;
    return true;
  }
  if (!f.is_object() || f.empty())
    return bad(error, "bad_field", std::string("\"recipe\" must be ") + (name_allowed ? "a saved recipe's name or " : "") +
                                       "an object of class to place, e.g. {\"bolt\": \"tray\", \"*\": \"bin\"}");
  for (const auto& [cls, place] : f.items())
    if (!printable(cls, 64) || !place.is_string() || !printable(place.get<std::string>(), 64))
      return bad(error, "bad_field", "\"recipe\": class and place must be names (1-64 printable characters)");
  out.recipe = f;
  return true;
}

bool required(const nlohmann::json& j, const std::string& cmd, std::initializer_list<const char*> keys, Error& error) {
  for (const char* k : keys)
    if (!j.contains(k)) return bad(error, "missing_field", cmd + " needs \"" + k + "\"");
  return true;
}

}  // namespace

bool is_jobs_command(Command c) {
  switch (c) {
    case Command::Sort: case Command::Clear: case Command::RecipeSave: case Command::History:
    case Command::Pause: case Command::Resume: case Command::Cancel:
      return true;
    default:
      return false;
  }
}

bool parse_jobs_fields(const nlohmann::json& j, const std::string& cmd, Request& out, Error& error) {
  for (const auto& [key, value] : j.items())
    if (key != "cmd" && !allowed(out.command).count(key))
      return bad(error, "bad_field", "unknown field \"" + key.substr(0, 40) + "\" for " + cmd);
  int64_t v = 0;
  if (j.contains("max_picks")) {
    if (!int_field(j, "max_picks", 1, 100000, v, error)) return false;
    out.max_picks = int(v);
  }
  switch (out.command) {
    case Command::Sort:
      return required(j, cmd, {"recipe"}, error) && recipe_field(j, out, error, true);
    case Command::Clear:
      return required(j, cmd, {"place"}, error) && string_field(j, "place", 64, out.place, error);
    case Command::RecipeSave:
      return required(j, cmd, {"name", "recipe"}, error) && string_field(j, "name", 64, out.name, error) &&
             recipe_field(j, out, error, false);
    case Command::History:
      if (j.contains("limit")) {
        if (!int_field(j, "limit", 1, 100000, v, error)) return false;
        out.limit = int(v);
      }
      if (j.contains("job")) {
        if (!int_field(j, "job", 1, INT32_MAX, v, error)) return false;
        out.job = int(v);
      }
      if (j.contains("since") && !string_field(j, "since", 40, out.since, error)) return false;
      if (j.contains("format")) {
        if (!string_field(j, "format", 8, out.format, error)) return false;
        if (out.format != "json" && out.format != "csv") return bad(error, "bad_field", "\"format\" must be \"json\" or \"csv\"");
      }
      return true;
    default:
      return true;
  }
}

void jobs_fields_json(const Request& r, nlohmann::json& j) {
  switch (r.command) {
    case Command::Sort:
      j["recipe"] = r.recipe;
      break;
    case Command::Clear: j["place"] = r.place; break;
    case Command::RecipeSave:
      j["name"] = r.name;
      j["recipe"] = r.recipe;
      break;
    case Command::History:
      if (r.limit) j["limit"] = r.limit;
      if (r.job) j["job"] = r.job;
      if (!r.since.empty()) j["since"] = r.since;
      if (!r.format.empty()) j["format"] = r.format;
      break;
    default: break;
  }
  if (r.max_picks && (r.command == Command::Sort || r.command == Command::Clear)) j["max_picks"] = r.max_picks;
}

}  // namespace rbx1::daemon
