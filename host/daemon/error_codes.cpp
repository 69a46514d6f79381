// error_codes.cpp - the list of error codes (GRBL keeps its codes in one CSV that host tools read; this is ours).
#include "error_codes.hpp"

namespace rbx1::daemon {

namespace {
using C = ErrorClass;
const std::vector<ErrorCode> kCodes = {
    {"bad_json", C::Request, "the request is not valid JSON"},
    {"bad_request", C::Request, "the request is not an object, or its fields contradict each other"},
    {"unknown_command", C::Request, "no such command (rbx1 commands lists them)"},
    {"missing_field", C::Request, "a field the command needs is absent"},
    {"bad_field", C::Request, "a field has the wrong type or is out of range, or is unknown"},
    {"line_too_long", C::Request, "the request line is longer than 4096 bytes"},
    {"too_large", C::Request, "an MQTT command larger than the interface takes"},
    {"busy", C::Job, "another job is running (or too many subscribers)"},
    {"not_ready", C::Job, "the link is down, the arm is not homed, or a fault waits for clear_fault"},
    {"shutting_down", C::Job, "rbx1d is stopping"},
    {"fault", C::Job, "the firmware reports a fault"},
    {"estop", C::Job, "an e-stop aborted the job"},
    {"estop_active", C::Job, "the e-stop input is still held"},
    {"object_absent", C::Job, "the named object is not in the scene (the arm went home)"},
    {"unknown_place", C::Job, "no such place in [arm] places or saved places"},
    {"plan_failed", C::Job, "no reachable motion for the grip"},
    {"out_of_limits", C::Job, "a target lies outside a joint's limits or below the table; nothing moved"},
    {"jog_too_far", C::Job, "a jog larger than [operator] allows"},
    {"camera_failed", C::Job, "the camera gave no frame"},
    {"vision_failed", C::Job, "the perception could not process the frame"},
    {"pick_failed", C::Job, "the pick check saw the object still there after the retries"},
    {"pick_unverified", C::Job, "the pick check's frame showed no object at all where the scan before found several, twice"},
    {"rejected", C::Job, "the firmware refused a step"},
    {"timeout", C::Job, "a step or the job took longer than allowed"},
    {"link_down", C::Job, "the serial link stayed down longer than reconnect_timeout_s"},
    {"link_error", C::Job, "the serial link failed a request"},
    {"firmware_reset", C::Job, "the firmware restarted mid-job and lost its positions"},
    {"stopped", C::Job, "motion was stopped by someone else"},
    {"shutdown", C::Job, "the job was aborted because rbx1d stopped"},
    {"state_failed", C::Job, "a file of the state directory could not be written"},
    {"bad_pose", C::Job, "the pose cannot be saved (unreachable or unknown)"},
    {"no_scan", C::Job, "teach needs a scan first"},
    {"no_object", C::Job, "no object with that index in the last scan"},
    {"uncalibrated", C::Job, "the command needs a calibration in force"},
    {"no_calibration", C::Job, "no workspace calibration session is open"},
    {"unknown_marker", C::Job, "no marker with that id on the sheet"},
    {"too_few_markers", C::Job, "the workspace fit needs more markers; the old calibration stays"},
    {"not_on_table", C::Job, "the tool point is not on the table plane"},
    {"fit_rejected", C::Job, "the workspace fit's error is above its limit; the old calibration stays"},
    {"bad_recipe", C::Job, "the recipe names a place or a class the arm does not know"},
    {"unknown_recipe", C::Job, "no saved recipe of that name (recipes.json)"},
    {"no_job", C::Job, "pause, resume or cancel with no sort or clear running"},
    {"cancelled", C::Job, "resume of a sort or clear that is being cancelled"},
    {"history_failed", C::Job, "the history database could not be read"},
    {"no_image", C::Job, "the history kept no image of that scan ([history] max_mb)"},
    {"internal", C::Job, "a bug: the job ended without a result"},
    {"unauthorized", C::Access, "the console's token is missing or wrong"},
    {"not_allowed", C::Access, "the command is not available from this client"},
    {"bad_origin", C::Access, "a request from another site's page"},
    {"not_found", C::Access, "no such resource"},
    {"too_many_streams", C::Access, "too many console streams are open"},
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

const std::vector<ErrorCode>& error_codes() { return kCodes; }

const ErrorCode* find_error(std::string_view code) {
  for (const auto& e : kCodes)
    if (code == e.code) return &e;
  return nullptr;
}

bool is_request_error(std::string_view code) {
  const ErrorCode* e = find_error(code);
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
