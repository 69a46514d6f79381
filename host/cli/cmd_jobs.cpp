// cmd_jobs.cpp - rbx1 sort|clear|recipe save|history: the cell's jobs through rbx1d (pause, resume, cancel come
// from the command table with the other requests that take no field).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "commands.hpp"

namespace rbx1::cli {

namespace {

struct JobsOptions {
  std::string socket = default_socket();
  bool json = false, csv = false;
  std::string recipe, place, name, file, since;
  int max_picks = 0, limit = 0;
  int job = 0;
};

CLI::App* add(CLI::App& parent, std::shared_ptr<JobsOptions> o, const char* name, const char* help) {
  CLI::App* sub = parent.add_subcommand(name, help);
  sub->add_option("--socket", o->socket, "rbx1d control socket (default $RBX1_SOCKET or /run/rbx1/rbx1d.sock)");
  sub->add_flag("--json", o->json, "print the raw JSON");
  return sub;
}

// A recipe file's JSON object, or null when path is not a readable file (then it names a saved recipe).
bool read_recipe_file(const std::string& path, nlohmann::json& out, std::string& error) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  out = nlohmann::json::parse(ss.str(), nullptr, false);
  if (out.is_discarded() || !out.is_object()) error = path + ": not a JSON object of class to place";
  return true;
}

// The history as a table: the jobs, then the picks (newest first, as rbx1d returns them).
void print_history(const nlohmann::json& h) {
  auto s = [](const nlohmann::json& v) { return v.is_null() ? std::string("-") : v.is_string() ? v.get<std::string>() : v.dump(); };
  std::printf("%-5s %-6s %-24s %-24s %-12s %s\n", "job", "kind", "started", "ended", "outcome", "recipe");
  for (const auto& j : h["jobs"])
    std::printf("%-5s %-6s %-24s %-24s %-12s %s\n", s(j["id"]).c_str(), s(j["kind"]).c_str(), s(j["started"]).c_str(),
                s(j["ended"]).c_str(), s(j["outcome"]).c_str(), s(j["recipe"]).c_str());
  std::printf("\n%-6s %-5s %-24s %-12s %-6s %-8s %-10s %-9s %s\n", "pick", "job", "time", "class", "score", "place",
              "outcome", "cycle_s", "reason");
  for (const auto& p : h["picks"]) {
    double cycle = p["cycle_ms"].is_number() ? p["cycle_ms"].get<double>() / 1000 : 0;
    std::string score = p["match_score"].is_number() ? std::to_string(p["match_score"].get<double>()).substr(0, 4) : "-";
    std::printf("%-6s %-5s %-24s %-12s %-6s %-8s %-10s %-9.1f %s\n", s(p["id"]).c_str(), s(p["job"]).c_str(),
                s(p["ts"]).c_str(), s(p["class"]).c_str(), score.c_str(), s(p["place"]).c_str(),
                s(p["outcome"]).c_str(), cycle, s(p["reason"]).c_str());
  }
}

}  // namespace

void add_jobs_commands(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<JobsOptions>();
  CLI::App* sort = add(app, o, "sort", "sort the table: each class to its recipe's place, until nothing mapped is left");
  sort->add_option("--recipe", o->recipe, "a saved recipe's name, or a JSON file {\"CLASS\": \"PLACE\", \"*\": ...}")
      ->required();
  sort->add_option("--max-picks", o->max_picks, "stop after this many picks")->check(CLI::PositiveNumber);
  sort->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::Sort;
    r.max_picks = o->max_picks;
    std::string error;
    if (read_recipe_file(o->recipe, r.recipe, error)) {
      if (!error.empty()) {
        std::fprintf(stderr, "rbx1: %s\n", error.c_str());
        exit_code = 2;
        return;
      }
    } else {
      r.recipe = o->recipe;
    }
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* clear = add(app, o, "clear", "clear the table: every pickable object to one place");
  clear->add_option("--place", o->place, "where everything goes (a place of the [arm] config)")->required();
  clear->add_option("--max-picks", o->max_picks, "stop after this many picks")->check(CLI::PositiveNumber);
  clear->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::Clear;
    r.place = o->place;
    r.max_picks = o->max_picks;
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* recipe = app.add_subcommand("recipe", "sort recipes kept by rbx1d (STATE_DIR/recipes.json)");
  recipe->require_subcommand(1);
  CLI::App* save = add(*recipe, o, "save", "save (or replace) a recipe under NAME, checked against places and library");
  save->add_option("name", o->name, "the recipe's name")->required();
  save->add_option("file", o->file, "a JSON file {\"CLASS\": \"PLACE\", \"*\": \"PLACE\", \"unknown\": \"PLACE\"}")
      ->required();
  save->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::RecipeSave;
    r.name = o->name;
    std::string error;
    if (!read_recipe_file(o->file, r.recipe, error) || !error.empty()) {
      std::fprintf(stderr, "rbx1: %s\n", error.empty() ? (o->file + ": no such file").c_str() : error.c_str());
      exit_code = 2;
      return;
    }
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* history = add(app, o, "history", "the jobs and picks rbx1d remembers (STATE_DIR/history.sqlite)");
  history->add_option("--since", o->since, "from this UTC time on (ISO-8601, or a prefix: 2026-12-02)");
  history->add_option("--job", o->job, "one job's rows")->check(CLI::PositiveNumber);
  history->add_option("--limit", o->limit, "rows of each kind (default 100)")->check(CLI::PositiveNumber);
  history->add_flag("--csv", o->csv, "the picks as CSV");
  history->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::History;
    r.since = o->since;
    r.job = o->job;
    r.limit = o->limit;
    if (o->csv) r.format = "csv";
    nlohmann::json result;
    exit_code = run_daemon_request(o->socket, false, r, &result, false, 10);
    if (exit_code != 0) return;
    if (o->csv) std::fputs(result.value("csv", "").c_str(), stdout);
    else if (o->json) std::printf("%s\n", result.dump().c_str());
    else print_history(result);
  });
  // pause, resume, cancel take no field: cmd_daemon.cpp makes them subcommands from the command table.
}

}  // namespace rbx1::cli
