// history.hpp - the jobs' history: every job and every pick attempt in STATE_DIR/history.sqlite (SQLite, WAL,
// one transaction per row), each scan's annotated JPEG beside it in STATE_DIR/scans/ within a disk budget.
#pragma once
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config.hpp"

struct sqlite3;

namespace rbx1::history {

inline constexpr const char* kHistoryFile = "history.sqlite";
inline constexpr const char* kScansDir = "scans";

// [history]
struct HistoryConfig {
  double max_mb = 200;  // scan images kept on disk, oldest removed first (rows are kept)
};
void parse_history_config(config::Section s, HistoryConfig& out);

// One pick attempt (or a skipped object: outcome "skipped", reason why).
struct PickRow {
  int64_t job = 0;
  std::string cls;                     // the library label, or "unknown"
  std::optional<double> match_score;
  std::optional<double> grip_opening_cm, grip_angle_deg;
  std::string place;                   // where it was to go ("" when skipped)
  nlohmann::json phases_ms = nlohmann::json::object();  // e.g. {"plan": 3, "move": 8200, "check": 900}
  double cycle_ms = 0;                 // from the decision to the next one's start
  std::string outcome;                 // picked | failed | skipped
  std::string reason;                  // "" when picked; still_there, infeasible_grip: too_wide, unreachable, ...
  int attempt = 1;
  std::optional<int64_t> scan;         // the scan the object was chosen from
};

// Query filters: since (ISO-8601 prefix compared as text, "" = all), job (0 = all), limit (rows of each kind).
struct Query {
  std::string since;
  int64_t job = 0;
  int limit = 1000;
};

class History {
 public:
  // Opens (creates) DIR/history.sqlite and DIR/scans/; marks jobs left running as "interrupted". A corrupt or
  // unreadable database is an error "PATH: reason; what to do" and the file is left untouched.
  static std::unique_ptr<History> open(const std::string& dir, const HistoryConfig& config, std::string& error);
  ~History();

  int interrupted_at_open() const { return interrupted_; }
  // Each write is one transaction; false + error on failure (the row is not there, nothing half-written).
  int64_t begin_job(const std::string& kind, const nlohmann::json& recipe, std::string& error);  // 0 on error
  bool end_job(int64_t job, const std::string& outcome, const nlohmann::json& summary, std::string& error);
  // A scan's row and its JPEG (may be empty: no image); then the oldest images beyond max_mb are removed.
  int64_t add_scan(int64_t job, int objects, const std::vector<unsigned char>& jpeg, std::string& error);
  int64_t add_pick(const PickRow& row, std::string& error);
  // One pick row as query() gives it (null when there is none): what the bus's picks topic carries.
  nlohmann::json pick(int64_t id, std::string& error);
  // {"jobs": [...], "picks": [...]}, newest first.
  nlohmann::json query(const Query& q, std::string& error);
  // The same picks as CSV (a header line, then one line per pick).
  static std::string picks_csv(const nlohmann::json& picks);
  std::string scan_path(int64_t scan) const;  // the JPEG of a scan ("" when none is kept)
  int64_t image_bytes() const;

 private:
  History() = default;
  bool exec(const char* sql, std::string& error);
  void prune_images();
  sqlite3* db_ = nullptr;
  std::string dir_, path_;
  HistoryConfig config_;
  int interrupted_ = 0;
  int64_t image_bytes_ = 0;
  mutable std::mutex mu_;  // one writer at a time; the query takes it too (a short read)
};

}  // namespace rbx1::history
