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

// The one list: X(name in C++, code on the wire, class, meaning). The wire codes are a contract clients test:
// never rename one. error_codes_markdown() writes this list into host/daemon/README.md (tools/check-command-table).
#define RBX1_ERROR_CODES(X)                                                                                       \
  X(BadJson, "bad_json", Request, "the request is not valid JSON")                                                \
  X(BadRequest, "bad_request", Request, "the request is not an object, or its fields contradict each other")      \
  X(UnknownCommand, "unknown_command", Request, "no such command (rbx1 commands lists them)")                     \
  X(MissingField, "missing_field", Request, "a field the command needs is absent")                                \
  X(BadField, "bad_field", Request, "a field has the wrong type or is out of range, or is unknown")               \
  X(LineTooLong, "line_too_long", Request, "the request line is longer than 4096 bytes")                          \
  X(TooLarge, "too_large", Request, "an MQTT command larger than the interface takes")                            \
  X(Stale, "stale", Request, "an MQTT command retained, older than [mqtt] max_age_s, or undated just after a reconnect") \
  X(Busy, "busy", Job, "another job is running (or too many subscribers)")                                        \
  X(NotReady, "not_ready", Job, "the link is down, the arm is not homed, or a fault waits for clear_fault")        \
  X(ShuttingDown, "shutting_down", Job, "rbx1d is stopping")                                                      \
  X(Fault, "fault", Job, "the firmware reports a fault")                                                          \
  X(Estop, "estop", Job, "an e-stop aborted the job")                                                             \
  X(EstopActive, "estop_active", Job, "the e-stop input is still held")                                           \
  X(ObjectAbsent, "object_absent", Job, "the named object is not in the scene (the arm went home)")               \
  X(UnknownPlace, "unknown_place", Job, "no such place in [arm] places or saved places")                          \
  X(PlanFailed, "plan_failed", Job, "no reachable motion for the grip")                                           \
  X(OutOfLimits, "out_of_limits", Job, "a target lies outside a joint's limits or below the table; nothing moved") \
  X(JogTooFar, "jog_too_far", Job, "a jog larger than [operator] allows")                                         \
  X(CameraFailed, "camera_failed", Job, "the camera gave no frame")                                               \
  X(VisionFailed, "vision_failed", Job, "the perception could not process the frame")                             \
  X(PickFailed, "pick_failed", Job, "the pick check saw the object still there after the retries")                \
  X(PickUnverified, "pick_unverified", Job, "a frame judging a pick (the pick check's, the sort's next scan) showed no object at all where the scan before found several, twice") \
  X(Rejected, "rejected", Job, "the firmware refused a step")                                                     \
  X(Timeout, "timeout", Job, "a step or the job took longer than allowed")                                        \
  X(LinkDown, "link_down", Job, "the serial link stayed down longer than reconnect_timeout_s")                    \
  X(LinkError, "link_error", Job, "the serial link failed a request")                                             \
  X(FirmwareReset, "firmware_reset", Job, "the firmware restarted mid-job and lost its positions")                \
  X(Stopped, "stopped", Job, "motion was stopped by someone else")                                                \
  X(Shutdown, "shutdown", Job, "the job was aborted because rbx1d stopped")                                       \
  X(Aborted, "aborted", Job, "the job was aborted by the daemon for a reason without a code of its own")       \
  X(ClientGone, "client_gone", Job, "the client of a jog went away mid-move: the arm stopped (the dead-man rule)") \
  X(StateFailed, "state_failed", Job, "a file of the state directory could not be written")                       \
  X(BadPose, "bad_pose", Job, "the pose cannot be saved (unreachable or unknown)")                                \
  X(NoScan, "no_scan", Job, "teach needs a scan first")                                                           \
  X(NoObject, "no_object", Job, "no object with that index in the last scan")                                     \
  X(Uncalibrated, "uncalibrated", Job, "the command needs a calibration in force")                                \
  X(NoCalibration, "no_calibration", Job, "no workspace calibration session is open")                             \
  X(UnknownMarker, "unknown_marker", Job, "no marker with that id on the sheet")                                  \
  X(TooFewMarkers, "too_few_markers", Job, "the workspace fit needs more markers; the old calibration stays")     \
  X(DuplicateMarker, "duplicate_marker", Job, "a marker was recorded twice; the old calibration stays")           \
  X(Degenerate, "degenerate", Job, "the markers are collinear or coincide; the old calibration stays")            \
  X(NotOnTable, "not_on_table", Job, "the tool point is not on the table plane")                                  \
  X(FitRejected, "fit_rejected", Job, "the workspace fit's error is above its limit; the old calibration stays")  \
  X(BadRecipe, "bad_recipe", Job, "the recipe names a place or a class the arm does not know")                    \
  X(UnknownRecipe, "unknown_recipe", Job, "no saved recipe of that name (recipes.json)")                          \
  X(NoJob, "no_job", Job, "pause, resume or cancel with no sort or clear running")                                \
  X(Cancelled, "cancelled", Job, "resume of a sort or clear that is being cancelled")                             \
  X(HistoryFailed, "history_failed", Job, "the history database could not be read")                               \
  X(NoImage, "no_image", Job, "the history kept no image of that scan ([history] max_mb)")                        \
  X(Internal, "internal", Job, "a bug: the job ended without a result")                                           \
  X(Unauthorized, "unauthorized", Access, "the console's token is missing or wrong")                              \
  X(NotAllowed, "not_allowed", Access, "the command is not available from this client")                           \
  X(BadOrigin, "bad_origin", Access, "a request from another site's page")                                        \
  X(NotFound, "not_found", Access, "no such resource")                                                            \
  X(TooManyStreams, "too_many_streams", Access, "too many console streams are open")

enum class ErrorCode {
#define RBX1_ERROR_ENUM(name, code, cls, meaning) name,
  RBX1_ERROR_CODES(RBX1_ERROR_ENUM)
#undef RBX1_ERROR_ENUM
};

struct ErrorInfo {
  ErrorCode id;
  const char* code;  // on the wire
  ErrorClass cls;
  const char* meaning;
};

const std::vector<ErrorInfo>& error_codes();
const ErrorInfo& error_info(ErrorCode id);
// The code as it goes on the wire ("not_ready").
const char* code_name(ErrorCode id);
const ErrorInfo* find_error(std::string_view code);
// True for codes of the request itself (bad_json, bad_field, ...).
bool is_request_error(std::string_view code);
nlohmann::json error_codes_json();
std::string error_codes_markdown();

}  // namespace rbx1::daemon
