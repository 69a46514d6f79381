// command_decode.hpp - one payload on <prefix>/cmd -> the socket request line plus its MQTT envelope (id, ts), and
// the stale rule. The request itself is parsed and checked by the request layer (parse_request), as on the socket.
#pragma once
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::mqtt {

// Largest payload looked at: a request line plus room for the envelope. Larger ones are refused unread.
inline constexpr size_t kMaxCommandPayload = daemon::kMaxRequestLine + 512;

struct Incoming {
  nlohmann::json id;          // the request's "id" (string or integer), null when absent
  std::optional<double> ts;   // "ts": when the sender sent it, Unix seconds (a number, or ISO-8601 UTC text)
  std::string cmd;            // the command's name when "cmd" is a string ("" otherwise)
  std::string line;           // the request without id and ts: what submit_line() gets
};

// Decodes the envelope. false with error (too_large, bad_json, bad_request, bad_field) for a payload that can
// never be a request; whatever else is wrong (unknown command, a field's type) the request layer reports. Never
// throws, whatever the bytes.
bool decode_command(std::string_view payload, Incoming& out, daemon::Error& error);

// "2026-11-22T01:02:03.456Z" -> Unix seconds; false for anything else.
bool parse_iso_utc(const std::string& text, double& seconds);

// Why a command must not run (error "stale"), or "" when it may: a retained message (it would run again at every
// subscription), one without ts received within the grace after a (re)connect (it may have waited in the broker
// through an outage), one whose ts is older than max_age_s (or that far in the future: a clock that disagrees).
std::string stale_reason(const Incoming& in, bool retained, double now_s, double max_age_s, bool just_connected);

// The final reply line with the request's id added (when it has one): what goes on cmd/response.
std::string with_id(const std::string& final_line, const nlohmann::json& id);

}  // namespace rbx1::mqtt
