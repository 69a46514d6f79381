// operator_request.cpp - the operator commands' request fields (jog, pose/place save, background, teach,
// calibrate_workspace): each field checked for type and range, every mistake an error value.
#include <cmath>
#include <set>

#include "request.hpp"

namespace rbx1::daemon {

namespace {

// Allowed fields per command (besides "cmd").
const std::set<std::string>& allowed(Command c) {
  static const std::set<std::string> jog{"joint", "steps", "deg", "mm"}, pose{"name"}, place{"name"},
      background{"frames"}, teach{"index", "name", "mirror_ok"}, calib{"action", "marker"}, none{};
  switch (c) {
    case Command::Jog: return jog;
    case Command::PoseSave: return pose;
    case Command::PlaceSave: return place;
    case Command::Background: return background;
    case Command::Teach: return teach;
    case Command::CalibrateWorkspace: return calib;
    default: return none;
  }
}

bool bad(Error& error, const std::string& code, const std::string& message) {
  error = {code, message};
  return false;
}

// An integer field within [lo, hi]; absent -> missing_field when required, else false without error (found=false).
bool integer(const nlohmann::json& j, const char* key, long long lo, long long hi, long long& out, bool& found,
             Error& error) {
  auto f = j.find(key);
  found = f != j.end();
  if (!found) return true;
  if (!f->is_number_integer() || f->get<long long>() < lo || f->get<long long>() > hi)
    return bad(error, "bad_field", std::string("\"") + key + "\" must be an integer in " + std::to_string(lo) + ".." +
                                       std::to_string(hi));
  out = f->get<long long>();
  return true;
}

bool name_field(const nlohmann::json& j, const std::string& cmd, Request& out, Error& error) {
  auto f = j.find("name");
  if (f == j.end()) return bad(error, "missing_field", cmd + " needs \"name\"");
  bool ok = f->is_string() && !f->get<std::string>().empty() && f->get<std::string>().size() <= 64;
  if (ok)
    for (unsigned char c : f->get<std::string>())
      if (c < 0x20 || c == 0x7f) ok = false;
  if (!ok) return bad(error, "bad_field", "\"name\" must be a non-empty string of at most 64 printable characters");
  out.name = f->get<std::string>();
  return true;
}

bool parse_jog(const nlohmann::json& j, Request& out, Error& error) {
  bool has_joint, has_steps = j.contains("steps"), has_deg = j.contains("deg"), has_mm = j.contains("mm");
  long long joint = 0, steps = 0;
  if (!integer(j, "joint", 1, 6, joint, has_joint, error)) return false;
  if (has_mm) {
    if (has_joint || has_steps || has_deg)
      return bad(error, "bad_request", "jog takes either \"mm\" (tool point) or \"joint\" with \"steps\" or \"deg\"");
    const auto& m = j["mm"];
    if (!m.is_array() || m.size() != 3)
      return bad(error, "bad_field", "\"mm\" must be [dx, dy, dz] in millimetres (base frame)");
    for (int i = 0; i < 3; ++i) {
      if (!m[i].is_number() || !std::isfinite(m[i].get<double>()))
        return bad(error, "bad_field", "\"mm\" must be [dx, dy, dz] in millimetres (base frame)");
      out.mm[i] = m[i].get<double>();
    }
    out.joint = 0;
    return true;
  }
  if (!has_joint) return bad(error, "missing_field", "jog needs \"joint\" (1..6) with \"steps\" or \"deg\", or \"mm\"");
  if (has_steps == has_deg) return bad(error, "bad_request", "jog of a joint takes exactly one of \"steps\" and \"deg\"");
  out.joint = int(joint);
  if (has_steps) {
    bool found;
    if (!integer(j, "steps", -1000000, 1000000, steps, found, error)) return false;
    out.steps = int32_t(steps);
    out.by_steps = true;
  } else {
    const auto& d = j["deg"];
    if (!d.is_number() || !std::isfinite(d.get<double>()) || std::fabs(d.get<double>()) > 360)
      return bad(error, "bad_field", "\"deg\" must be a number of degrees in -360..360");
    out.deg = d.get<double>();
  }
  return true;
}

}  // namespace

bool is_operator_command(Command c) {
  return c == Command::Jog || c == Command::PoseSave || c == Command::PlaceSave || c == Command::Background ||
         c == Command::Teach || c == Command::CalibrateWorkspace;
}

bool parse_operator_fields(const nlohmann::json& j, const std::string& cmd, Request& out, Error& error) {
  const auto& ok = allowed(out.command);
  for (const auto& [key, value] : j.items())
    if (key != "cmd" && !ok.count(key))
      return bad(error, "bad_field", "unknown field \"" + key.substr(0, 40) + "\" for " + cmd);
  bool found = false;
  long long v = 0;
  switch (out.command) {
    case Command::Jog: return parse_jog(j, out, error);
    case Command::PoseSave:
      if (!name_field(j, cmd, out, error)) return false;
      if (out.name != "scan") return bad(error, "bad_field", "pose_save: only the \"scan\" pose is taught (got \"" + out.name + "\")");
      return true;
    case Command::PlaceSave: return name_field(j, cmd, out, error);
    case Command::Background:
      if (!integer(j, "frames", 1, 64, v, found, error)) return false;
      out.frames = found ? int(v) : 0;
      return true;
    case Command::Teach:
      if (!name_field(j, cmd, out, error)) return false;
      if (!integer(j, "index", 1, 1000, v, found, error)) return false;
      if (!found) return bad(error, "missing_field", "teach needs \"index\" (the object's number in the live scan)");
      out.index = int(v);
      if (j.contains("mirror_ok")) {
        if (!j["mirror_ok"].is_boolean()) return bad(error, "bad_field", "\"mirror_ok\" must be true or false");
        out.mirror_ok = j["mirror_ok"].get<bool>();
      }
      return true;
    case Command::CalibrateWorkspace: {
      auto a = j.find("action");
      if (a == j.end()) return bad(error, "missing_field", "calibrate_workspace needs \"action\"");
      static const std::set<std::string> actions{"start", "status", "record", "fit", "save", "cancel"};
      if (!a->is_string() || !actions.count(a->get<std::string>()))
        return bad(error, "bad_field", "\"action\" must be one of start, status, record, fit, save, cancel");
      out.action = a->get<std::string>();
      if (!integer(j, "marker", 0, 999, v, found, error)) return false;
      if (out.action == "record" && !found) return bad(error, "missing_field", "record needs \"marker\" (its id)");
      if (out.action != "record" && found) return bad(error, "bad_field", "\"marker\" belongs to action record only");
      out.index = int(v);
      return true;
    }
    default: return true;
  }
}

void operator_fields_json(const Request& r, nlohmann::json& j) {
  switch (r.command) {
    case Command::Jog:
      if (r.joint == 0) {
        j["mm"] = r.mm;
      } else {
        j["joint"] = r.joint;
        if (r.by_steps) j["steps"] = r.steps;
        else j["deg"] = r.deg;
      }
      break;
    case Command::PoseSave:
    case Command::PlaceSave: j["name"] = r.name; break;
    case Command::Background:
      if (r.frames > 0) j["frames"] = r.frames;
      break;
    case Command::Teach:
      j["index"] = r.index;
      j["name"] = r.name;
      if (r.mirror_ok) j["mirror_ok"] = true;
      break;
    case Command::CalibrateWorkspace:
      j["action"] = r.action;
      if (r.action == "record") j["marker"] = r.index;
      break;
    default: break;
  }
}

}  // namespace rbx1::daemon
