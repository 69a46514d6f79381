// command_table.hpp - every request the daemon takes, declared once: its name, its fields (type, range, where the
// value lands in Request), who may call it, whether it is a job, and its one-line help. The socket's parser, the
// console's routes and token rule, the CLI's help, the MQTT interface and the README's table all read this table.
#pragma once
#include <array>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::daemon {

// Who may call a command. The console's token classes: Read and Estop need the token only beyond loopback, Act
// always when one is set; Local commands are taken from the Unix socket only (its file mode is the access rule).
enum class Access { Read, Estop, Act, Local };
// Immediate commands are answered at once from any thread; a Job runs on the worker, one at a time ("busy").
enum class Mode { Immediate, Job };

enum class FieldType {
  Name,     // a non-empty string of at most 64 printable characters (labels, places)
  Choice,   // one of `choices` ("a|b|c")
  Integer,  // an integer in [lo, hi]
  Number,   // a finite number in [lo, hi]
  Flag,     // true or false
  Vec3,     // [x, y, z], finite numbers
  Names,    // a non-empty array of Name, each one of `choices` when given
  Any,      // any JSON value; the command's check judges it
};

using FieldSlot = std::variant<std::string Request::*, int Request::*, double Request::*, bool Request::*,
                               std::array<double, 3> Request::*, std::vector<std::string> Request::*,
                               nlohmann::json Request::*>;

struct Field {
  const char* key;
  FieldType type;
  bool required;
  FieldSlot slot;
  const char* help;
  double lo = 0, hi = 0;          // Integer, Number
  const char* choices = nullptr;  // Choice, Names
};

struct CommandSpec {
  Command command;
  const char* name;
  Access access;
  Mode mode;
  const char* help;
  std::vector<Field> fields;
  // Rules across fields (jog's two forms, record's marker): false with error set. Runs after every field passed.
  bool (*check)(const nlohmann::json& request, Request& out, Error& error) = nullptr;
  // The request's JSON where "non-default fields" is not enough (jog's forms); null: the generic rule.
  void (*write)(const Request& r, nlohmann::json& out) = nullptr;
  // A job that runs until the table is done (sort, clear): the event saying it started. A client that cannot wait
  // that long (the console's HTTP request) is answered with it, and follows the rest on the bus. null: none.
  const char* started_event = nullptr;
};

// A FieldType::Name value: a non-empty string of at most 64 printable characters.
bool valid_name(const nlohmann::json& v);
const std::vector<CommandSpec>& command_table();
// Checks a request object's fields against spec and stores them in out (out.command already set); false with error.
bool parse_fields(const CommandSpec& spec, const nlohmann::json& request, Request& out, Error& error);
const CommandSpec* find_command(std::string_view name);
const CommandSpec& command_spec(Command c);
const char* access_name(Access a);
// The table as JSON (name, access, mode, help, fields) and as the README's Markdown table (`rbx1 commands`).
nlohmann::json command_table_json();
std::string command_table_markdown();

}  // namespace rbx1::daemon
