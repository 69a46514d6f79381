// command_table.cpp - the table of requests, and the generic reading and writing of their fields.
#include "command_table.hpp"

#include <algorithm>
#include <cmath>

#include "jobs_request.hpp"
#include "rbx1_messages.h"

namespace rbx1::daemon {

namespace {

bool bad(Error& error, ErrorCode code, const std::string& message) {
  error = {code, message};
  return false;
}

// jog: one joint by steps or degrees, or the tool point by [dx, dy, dz] millimetres.
bool check_jog(const nlohmann::json& j, Request& r, Error& e) {
  bool joint = j.contains("joint"), steps = j.contains("steps"), deg = j.contains("deg");
  if (j.contains("mm")) {
    if (joint || steps || deg)
      return bad(e, ErrorCode::BadRequest, "jog takes either \"mm\" (tool point) or \"joint\" with \"steps\" or \"deg\"");
    r.joint = 0;
    return true;
  }
  if (!joint)
    return bad(e, ErrorCode::MissingField, "jog needs \"joint\" (1.." + std::to_string(RBX1_JOINTS) +
                                       ") with \"steps\" or \"deg\", or \"mm\"");
  if (steps == deg) return bad(e, ErrorCode::BadRequest, "jog of a joint takes exactly one of \"steps\" and \"deg\"");
  r.by_steps = steps;
  return true;
}

void write_jog(const Request& r, nlohmann::json& j) {
  if (r.joint == 0) {
    j["mm"] = r.mm;
    return;
  }
  j["joint"] = r.joint;
  if (r.by_steps) j["steps"] = r.steps;
  else j["deg"] = r.deg;
}

bool check_pose_save(const nlohmann::json&, Request& r, Error& e) {
  if (r.name == "scan") return true;
  return bad(e, ErrorCode::BadField, "pose_save: only the \"scan\" pose is taught (got \"" + r.name + "\")");
}

bool check_calibrate(const nlohmann::json& j, Request& r, Error& e) {
  bool marker = j.contains("marker");
  if (r.action == "record" && !marker) return bad(e, ErrorCode::MissingField, "record needs \"marker\" (its id)");
  if (r.action != "record" && marker) return bad(e, ErrorCode::BadField, "\"marker\" belongs to action record only");
  return true;
}

void write_calibrate(const Request& r, nlohmann::json& j) {
  j["action"] = r.action;
  if (r.action == "record") j["marker"] = r.index;
}

// The topics of the bus (bus.hpp), as a subscribe request names them.
constexpr const char* kTopicNames = "status|events|scans|picks";

using F = FieldType;
// Never destroyed: a detached thread's reply may still name its command while the process exits.
const std::vector<CommandSpec>& kTable = *new std::vector<CommandSpec>{
    {Command::Status, "status", Access::Read, Mode::Immediate, "the arm's state: ready, job, link, joints, calibration", {}},
    {Command::Scan, "scan", Access::Act, Mode::Job, "move to the scan pose, capture, detect; the paper's report", {}},
    {Command::Pick, "pick", Access::Act, Mode::Job, "pick the named object and put it at a place",
     {{"name", F::Name, true, &Request::name, "the object's library label"},
      {"place", F::Name, true, &Request::place, "a place of [arm] places"}}},
    {Command::Home, "home", Access::Act, Mode::Job, "move to the home pose", {}},
    {Command::Estop, "estop", Access::Estop, Mode::Immediate, "stop at once and latch (clear_fault releases)", {}},
    {Command::ClearFault, "clear_fault", Access::Act, Mode::Job, "release a latched e-stop or fault after a check", {}},
    {Command::Shutdown, "shutdown", Access::Local, Mode::Immediate, "stop the daemon (the Unix socket only)", {}},
    {Command::Jog, "jog", Access::Act, Mode::Job, "move one joint by steps or degrees, or the tool point by mm",
     {{"joint", F::Integer, false, &Request::joint, "the joint's number, from 1", 1, RBX1_JOINTS},
      {"steps", F::Integer, false, &Request::steps, "steps to move the joint", -1000000, 1000000},
      {"deg", F::Number, false, &Request::deg, "degrees to move the joint", -360, 360},
      {"mm", F::Vec3, false, &Request::mm, "[dx, dy, dz] of the tool point, millimetres, base frame"}},
     check_jog, write_jog},
    {Command::PoseSave, "pose_save", Access::Act, Mode::Job, "save the current joints as the scan pose",
     {{"name", F::Name, true, &Request::name, "\"scan\""}}, check_pose_save},
    {Command::PlaceSave, "place_save", Access::Act, Mode::Job, "save the tool point as a named place",
     {{"name", F::Name, true, &Request::name, "the place's name"}}},
    {Command::Background, "background", Access::Act, Mode::Job, "capture the empty table as the background",
     {{"frames", F::Integer, false, &Request::frames, "frames to average", 1, 64}}},
    {Command::Teach, "teach", Access::Act, Mode::Job, "add an object of the live scan to the library",
     {{"index", F::Integer, true, &Request::index, "the object's number in the live scan", 1, 1000},
      {"name", F::Name, true, &Request::name, "its label"},
      {"mirror_ok", F::Flag, false, &Request::mirror_ok, "its mirror image is the same object"}}},
    {Command::CalibrateWorkspace, "calibrate_workspace", Access::Act, Mode::Job,
     "the workspace calibration: start, status, record, fit, save, cancel",
     {{"action", F::Choice, true, &Request::action, "the step", 0, 0, "start|status|record|fit|save|cancel"},
      {"marker", F::Integer, false, &Request::index, "record: the marker's id", 0, 999}},
     check_calibrate, write_calibrate},
    {Command::Subscribe, "subscribe", Access::Read, Mode::Immediate,
     "stream the bus (status, events, scans, picks) as JSON lines until the client closes",
     {{"topics", F::Names, false, &Request::topics, "topics to stream (default: all)", 0, 0, kTopicNames}}},
    {Command::Scene, "scene", Access::Read, Mode::Immediate,
     "the arm's world for a 3D view: URDF, table, places, camera view, the last scan's objects in the base frame", {}},
    // The cell's jobs (sort_jobs.cpp; jobs_request.cpp checks the recipe).
    {Command::Sort, "sort", Access::Act, Mode::Job,
     "sort the table: each class to its recipe's place, until nothing the recipe maps is left",
     {{"recipe", F::Any, true, &Request::recipe, "a saved recipe's name, or {\"CLASS\": \"PLACE\", \"*\": ..., \"unknown\": ...}"},
      {"max_picks", F::Integer, false, &Request::max_picks, "stop after this many picks", 1, 100000}},
     check_sort_request, nullptr, "sort_started"},
    {Command::Clear, "clear", Access::Act, Mode::Job, "clear the table: every pickable object to one place",
     {{"place", F::Name, true, &Request::place, "a place of [arm] places"},
      {"max_picks", F::Integer, false, &Request::max_picks, "stop after this many picks", 1, 100000}},
     nullptr, nullptr, "sort_started"},
    {Command::RecipeSave, "recipe_save", Access::Act, Mode::Immediate,
     "save a recipe (checked against places and library) in STATE_DIR/recipes.json",
     {{"name", F::Name, true, &Request::name, "the recipe's name"},
      {"recipe", F::Any, true, &Request::recipe, "{\"CLASS\": \"PLACE\", \"*\": \"PLACE\", \"unknown\": \"PLACE\"}"}},
     check_recipe_save_request},
    {Command::History, "history", Access::Read, Mode::Immediate, "the jobs and pick attempts of STATE_DIR/history.sqlite",
     {{"limit", F::Integer, false, &Request::limit, "rows of each kind (default 100)", 1, 100000},
      {"job", F::Integer, false, &Request::job, "one job's rows", 1, 2147483647},
      {"since", F::Name, false, &Request::since, "rows from this UTC time (ISO-8601 or a prefix)"},
      {"format", F::Choice, false, &Request::format, "json (default) or csv (adds \"csv\")", 0, 0, "json|csv"}}},
    {Command::Pause, "pause", Access::Act, Mode::Immediate, "pause the sort or clear after the pick under way", {}},
    {Command::Resume, "resume", Access::Act, Mode::Immediate, "resume a paused sort or clear", {}},
    {Command::Cancel, "cancel", Access::Act, Mode::Immediate, "cancel the sort or clear after the pick under way; home", {}},
    {Command::Recipes, "recipes", Access::Read, Mode::Immediate,
     "the saved recipes (STATE_DIR/recipes.json), with the classes and places a recipe may name", {}},
};

std::vector<std::string> split_choices(const char* choices) {
  std::vector<std::string> out;
  std::string s = choices ? choices : "";
  for (size_t start = 0; start <= s.size();) {
    size_t bar = s.find('|', start);
    if (bar == std::string::npos) bar = s.size();
    out.push_back(s.substr(start, bar - start));
    start = bar + 1;
  }
  return out;
}

std::string range_text(const Field& f) {
  auto num = [](double v) {
    std::string s = std::to_string(v);
    if (v == std::floor(v)) s = std::to_string((long long)v);
    return s;
  };
  return num(f.lo) + ".." + num(f.hi);
}

bool one_of(const std::string& v, const char* choices) {
  for (const auto& c : split_choices(choices))
    if (v == c) return true;
  return false;
}

// Checks one present field's value and stores it in out; false with error set.
bool read_field(const Field& f, const nlohmann::json& v, Request& out, Error& e) {
  const std::string key = std::string("\"") + f.key + "\"";
  switch (f.type) {
    case F::Name:
      if (!valid_name(v)) return bad(e, ErrorCode::BadField, key + " must be a non-empty string of at most 64 printable characters");
      out.*std::get<std::string Request::*>(f.slot) = v.get<std::string>();
      return true;
    case F::Choice: {
      std::string all = f.choices;
      std::replace(all.begin(), all.end(), '|', ',');
      if (!v.is_string() || !one_of(v.get<std::string>(), f.choices))
        return bad(e, ErrorCode::BadField, key + " must be one of " + all);
      out.*std::get<std::string Request::*>(f.slot) = v.get<std::string>();
      return true;
    }
    case F::Integer:
      if (!v.is_number_integer() || double(v.get<long long>()) < f.lo || double(v.get<long long>()) > f.hi)
        return bad(e, ErrorCode::BadField, key + " must be an integer in " + range_text(f));
      out.*std::get<int Request::*>(f.slot) = int(v.get<long long>());
      return true;
    case F::Number:
      if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < f.lo || v.get<double>() > f.hi)
        return bad(e, ErrorCode::BadField, key + " must be a number in " + range_text(f));
      out.*std::get<double Request::*>(f.slot) = v.get<double>();
      return true;
    case F::Flag:
      if (!v.is_boolean()) return bad(e, ErrorCode::BadField, key + " must be true or false");
      out.*std::get<bool Request::*>(f.slot) = v.get<bool>();
      return true;
    case F::Vec3: {
      bool ok = v.is_array() && v.size() == 3;
      for (size_t i = 0; ok && i < 3; ++i) ok = v[i].is_number() && std::isfinite(v[i].get<double>());
      if (!ok) return bad(e, ErrorCode::BadField, key + " must be [dx, dy, dz] in millimetres (base frame)");
      auto& a = out.*std::get<std::array<double, 3> Request::*>(f.slot);
      for (size_t i = 0; i < 3; ++i) a[i] = v[i].get<double>();
      return true;
    }
    case F::Names: {
      bool ok = v.is_array() && !v.empty() && v.size() <= 16;
      for (size_t i = 0; ok && i < v.size(); ++i)
        ok = valid_name(v[i]) && (!f.choices || one_of(v[i].get<std::string>(), f.choices));
      if (!ok) return bad(e, ErrorCode::BadField, key + " must be a non-empty array of names" +
                                           (f.choices ? std::string(" from ") + f.choices : std::string()));
      out.*std::get<std::vector<std::string> Request::*>(f.slot) = v.get<std::vector<std::string>>();
      return true;
    }
    case F::Any:
      out.*std::get<nlohmann::json Request::*>(f.slot) = v;
      return true;
  }
  return bad(e, ErrorCode::Internal, "field type");
}

// A field's value in out as JSON, or null when it holds its default (not sent).
nlohmann::json field_value(const Field& f, const Request& r) {
  return std::visit(
      [&](auto member) -> nlohmann::json {
        const auto& v = r.*member;
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, nlohmann::json>) return v;
        else if (v == T{}) return nullptr;
        else return v;
      },
      f.slot);
}

const char* type_name(FieldType t) {
  switch (t) {
    case F::Name: return "name";
    case F::Choice: return "choice";
    case F::Integer: return "integer";
    case F::Number: return "number";
    case F::Flag: return "bool";
    case F::Vec3: return "[x,y,z]";
    case F::Names: return "[names]";
    case F::Any: return "json";
  }
  return "?";
}

}  // namespace

bool valid_name(const nlohmann::json& v) {
  if (!v.is_string()) return false;
  const auto& s = v.get_ref<const std::string&>();
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}

const std::vector<CommandSpec>& command_table() { return kTable; }

const CommandSpec* find_command(std::string_view name) {
  for (const auto& c : kTable)
    if (name == c.name) return &c;
  return nullptr;
}

const CommandSpec& command_spec(Command c) {
  for (const auto& s : kTable)
    if (s.command == c) return s;
  return kTable.front();  // every Command has an entry (command_table_test)
}

const char* command_name(Command c) { return command_spec(c).name; }

const char* access_name(Access a) {
  switch (a) {
    case Access::Read: return "read";
    case Access::Estop: return "estop";
    case Access::Act: return "act";
    case Access::Local: return "local";
  }
  return "?";
}

bool parse_fields(const CommandSpec& spec, const nlohmann::json& j, Request& out, Error& error) {
  for (const auto& [key, value] : j.items()) {
    if (key == "cmd") continue;
    bool known = false;
    for (const auto& f : spec.fields) known = known || key == f.key;
    if (!known) return bad(error, ErrorCode::BadField, "unknown field \"" + key.substr(0, 40) + "\" for " + spec.name);
  }
  for (const auto& f : spec.fields) {
    auto v = j.find(f.key);
    if (v == j.end()) {
      if (f.required) return bad(error, ErrorCode::MissingField, std::string(spec.name) + " needs \"" + f.key + "\" (" + f.help + ")");
      continue;
    }
    if (!read_field(f, *v, out, error)) return false;
  }
  return !spec.check || spec.check(j, out, error);
}

nlohmann::json request_json(const Request& r) {
  const CommandSpec& spec = command_spec(r.command);
  nlohmann::json j{{"cmd", spec.name}};
  if (spec.write) {
    spec.write(r, j);
    return j;
  }
  for (const auto& f : spec.fields) {
    nlohmann::json v = field_value(f, r);
    if (!v.is_null() || f.required) j[f.key] = v;
  }
  return j;
}

nlohmann::json command_table_json() {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& c : kTable) {
    nlohmann::json fields = nlohmann::json::array();
    for (const auto& f : c.fields) {
      nlohmann::json jf{{"key", f.key}, {"type", type_name(f.type)}, {"required", f.required}, {"help", f.help}};
      if (f.type == F::Integer || f.type == F::Number) jf["range"] = {f.lo, f.hi};
      if (f.choices) jf["choices"] = split_choices(f.choices);
      fields.push_back(jf);
    }
    out.push_back({{"name", c.name}, {"access", access_name(c.access)},
                   {"mode", c.mode == Mode::Job ? "job" : "immediate"}, {"help", c.help}, {"fields", fields}});
  }
  return out;
}

std::string command_table_markdown() {
  std::string md = "| request | fields | access | runs | what it does |\n|---|---|---|---|---|\n";
  for (const auto& c : kTable) {
    std::string fields;
    for (const auto& f : c.fields) {
      if (!fields.empty()) fields += ", ";
      std::string t = f.type == F::Integer || f.type == F::Number ? range_text(f)
                      : f.choices                                ? std::string(f.choices)
                                                                 : std::string(type_name(f.type));
      std::replace(t.begin(), t.end(), '|', '/');
      fields += std::string("`") + f.key + "`" + (f.required ? "" : "?") + " " + t;
    }
    md += std::string("| `") + c.name + "` | " + (fields.empty() ? "-" : fields) + " | " + access_name(c.access) +
          " | " + (c.mode == Mode::Job ? "job" : "at once") + " | " + c.help + " |\n";
  }
  return md;
}

}  // namespace rbx1::daemon
