// request.hpp - the control socket's request lines: parsing and validation into a typed Request, or an error reply.
// What each command takes is declared in command_table.hpp.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

#include "error_codes.hpp"

namespace rbx1::daemon {

// Longest request line accepted (bytes, newline excluded); longer lines get error "line_too_long".
inline constexpr size_t kMaxRequestLine = 4096;

enum class Command {
  Status, Scan, Pick, Home, Estop, ClearFault, Shutdown,
  // The operator's commands (host/daemon/README.md "Operator commands").
  Jog, PoseSave, PlaceSave, Background, Teach, CalibrateWorkspace,
  Subscribe,
  Scene,  // the console's 3D view (scene.hpp)
  // The cell's jobs and their control (sort_jobs.cpp; jobs_request.cpp checks the recipe).
  Sort, Clear, RecipeSave, History, Pause, Resume, Cancel, Recipes,
};

struct Request {
  Command command = Command::Status;
  std::string name;   // pick: the object's library label; pose_save, place_save, teach: the name to save
  std::string place;  // pick: a place name from [arm] places
  // jog: joint 1..RBX1_JOINTS with steps or deg, or joint 0 with mm (the tool point's Cartesian step, yaw kept).
  int joint = 0;
  int32_t steps = 0;
  double deg = 0;
  bool by_steps = false;
  std::array<double, 3> mm{};
  int index = 0;       // teach: the object's index in the live scan; calibrate_workspace record: the marker id
  int frames = 0;      // background: frames to average (0 = [operator] background_frames)
  bool mirror_ok = false;  // teach
  std::string action;  // calibrate_workspace: start, status, record, fit, save, cancel
  std::vector<std::string> topics;  // subscribe: bus topics (empty: all)
  // sort: a saved recipe's name (a string) or the recipe itself (class -> place); recipe_save: name and recipe.
  nlohmann::json recipe;
  int max_picks = 0;   // sort, clear: 0 = no limit
  int limit = 0;       // history: rows of each kind (0 = the default)
  int job = 0;         // history: one job's rows (0 = all)
  std::string since;   // history: rows from this ISO-8601 time (a prefix: "2026-12-02")
  std::string format;  // history: "json" (default) or "csv"
};

// An error reply: {"error": {"code": code, "message": message}}. Codes are stable strings clients test, made from
// the one list (error_codes.hpp) only.
struct Error {
  Error() = default;
  Error(ErrorCode id, std::string text) : code(code_name(id)), message(std::move(text)) {}
  std::string code;
  std::string message;
};
static_assert(!std::is_constructible_v<Error, const char*, std::string>, "an Error's code is an ErrorCode, never a string");

const char* command_name(Command c);
// One request line (without its newline) -> Request, or an Error (bad_json, bad_request, unknown_command,
// missing_field, bad_field). Never throws.
bool parse_request(std::string_view line, Request& out, Error& error);
// The request as a JSON line (what the client sends).
nlohmann::json request_json(const Request& r);

// Reply lines.
nlohmann::json error_reply(const Error& e);
nlohmann::json result_reply(nlohmann::json result);

}  // namespace rbx1::daemon
