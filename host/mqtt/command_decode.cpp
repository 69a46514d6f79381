// command_decode.cpp - the MQTT envelope of a request (id, ts) and the stale rule; never throws on any payload.
#include "command_decode.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>

namespace rbx1::mqtt {

namespace {
bool valid_id(const nlohmann::json& id) {
  if (id.is_number_integer() || id.is_number_unsigned()) return true;
  if (!id.is_string()) return false;
  const auto& s = id.get_ref<const std::string&>();
  if (s.empty() || s.size() > 128) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}

std::string fmt_seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f", s);
  return buf;
}
}  // namespace

bool parse_iso_utc(const std::string& text, double& seconds) {
  int y, mo, d, h, mi, n = 0;
  double s;
  if (text.size() > 40 || std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%lf%n", &y, &mo, &d, &h, &mi, &s, &n) != 6)
    return false;
  if (size_t(n) + 1 != text.size() || text.back() != 'Z') return false;
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || !(s >= 0 && s < 61)) return false;
  tm t{};
  t.tm_year = y - 1900;
  t.tm_mon = mo - 1;
  t.tm_mday = d;
  t.tm_hour = h;
  t.tm_min = mi;
  seconds = double(timegm(&t)) + s;
  return true;
}

bool decode_command(std::string_view payload, Incoming& out, daemon::Error& error) {
  out = Incoming{};
  if (payload.size() > kMaxCommandPayload) {
    error = {daemon::ErrorCode::TooLarge, "command larger than " + std::to_string(kMaxCommandPayload) + " bytes"};
    return false;
  }
  nlohmann::json j = nlohmann::json::parse(payload, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    error = {daemon::ErrorCode::BadJson, "command is not valid JSON"};
    return false;
  }
  if (!j.is_object()) {
    error = {daemon::ErrorCode::BadRequest, "command must be a JSON object"};
    return false;
  }
  if (auto id = j.find("id"); id != j.end()) {
    if (!valid_id(*id)) {
      error = {daemon::ErrorCode::BadField, "\"id\" must be an integer or a string of 1..128 printable characters"};
      return false;
    }
    out.id = *id;
    j.erase(id);
  }
  if (auto ts = j.find("ts"); ts != j.end()) {
    double seconds = 0;
    if (ts->is_number() && std::isfinite(ts->get<double>())) seconds = ts->get<double>();
    else if (!ts->is_string() || !parse_iso_utc(ts->get<std::string>(), seconds)) {
      error = {daemon::ErrorCode::BadField, "\"ts\" must be Unix seconds or ISO-8601 UTC (2026-11-22T01:02:03.456Z)"};
      return false;
    }
    out.ts = seconds;
    j.erase(ts);
  }
  if (auto cmd = j.find("cmd"); cmd != j.end() && cmd->is_string()) out.cmd = cmd->get<std::string>();
  out.line = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return true;
}

std::string stale_reason(const Incoming& in, bool retained, double now_s, double max_age_s, bool just_connected) {
  if (retained) return "a retained command is never run (it would run again at every subscription)";
  if (!in.ts) {
    if (just_connected)
      return "received right after a reconnect without \"ts\": it may have waited in the broker; send it again "
             "with \"ts\"";
    return "";
  }
  double age = now_s - *in.ts;
  // Whole seconds, printed as doubles: a ts of 1e300 must not overflow a conversion to an integer.
  if (age > max_age_s) return "sent " + fmt_seconds(age) + " s ago (mqtt.max_age_s " + fmt_seconds(max_age_s) + ")";
  if (age < -max_age_s) return "\"ts\" is " + fmt_seconds(-age) + " s in the future: check the clocks";
  return "";
}

std::string with_id(const std::string& final_line, const nlohmann::json& id) {
  if (id.is_null()) return final_line;
  nlohmann::json j = nlohmann::json::parse(final_line, nullptr, false);
  if (!j.is_object()) return final_line;
  j["id"] = id;
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rbx1::mqtt
