// history.cpp - the history database: schema, one transaction per row, jobs left running marked interrupted, the
// scan images' disk budget, queries as JSON and CSV.
#include "history.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>

#include "atomic_file.hpp"

namespace rbx1::history {

namespace fs = std::filesystem;

namespace {

constexpr const char* kSchema = R"(
CREATE TABLE IF NOT EXISTS jobs(id INTEGER PRIMARY KEY, kind TEXT NOT NULL, recipe TEXT, started TEXT NOT NULL,
  ended TEXT, outcome TEXT NOT NULL, summary TEXT);
CREATE TABLE IF NOT EXISTS scans(id INTEGER PRIMARY KEY, job INTEGER, ts TEXT NOT NULL, objects INTEGER, image TEXT);
CREATE TABLE IF NOT EXISTS picks(id INTEGER PRIMARY KEY, job INTEGER NOT NULL, ts TEXT NOT NULL, class TEXT,
  match_score REAL, grip_opening_cm REAL, grip_angle_deg REAL, place TEXT, phases_ms TEXT, cycle_ms REAL,
  outcome TEXT NOT NULL, reason TEXT, attempt INTEGER, scan INTEGER);
CREATE INDEX IF NOT EXISTS picks_job ON picks(job);
PRAGMA user_version = 1;
)";

std::string iso_now() {
  auto now = std::chrono::system_clock::now();
  auto t = std::chrono::system_clock::to_time_t(now);
  int ms = int(std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];  // room for any int the format could print (the compiler checks)
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1,
                tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
  return buf;
}

// A prepared statement that finalizes itself; bind() by position from 1.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) { rc_ = sqlite3_prepare_v2(db, sql, -1, &s_, nullptr); }
  ~Stmt() { sqlite3_finalize(s_); }
  bool ok() const { return rc_ == SQLITE_OK; }
  void bind(int i, const std::string& v) { sqlite3_bind_text(s_, i, v.c_str(), int(v.size()), SQLITE_TRANSIENT); }
  void bind(int i, int64_t v) { sqlite3_bind_int64(s_, i, v); }
  void bind(int i, std::optional<double> v) {
    if (v) sqlite3_bind_double(s_, i, *v);
    else sqlite3_bind_null(s_, i);
  }
  void bind_null(int i) { sqlite3_bind_null(s_, i); }
  int step() { return sqlite3_step(s_); }
  nlohmann::json column(int i) const {
    switch (sqlite3_column_type(s_, i)) {
      case SQLITE_INTEGER: return sqlite3_column_int64(s_, i);
      case SQLITE_FLOAT: return sqlite3_column_double(s_, i);
      case SQLITE_TEXT: return std::string(reinterpret_cast<const char*>(sqlite3_column_text(s_, i)));
      default: return nullptr;
    }
  }
  std::string error() const { return sqlite3_errmsg(db_); }

 private:
  sqlite3* db_;
  sqlite3_stmt* s_ = nullptr;
  int rc_;
};

// Runs a one-row write; the id of the row it inserted (or 1 for an update), 0 on error.
int64_t run_write(sqlite3* db, Stmt& st, std::string& error) {
  if (!st.ok() || st.step() != SQLITE_DONE) {
    error = st.error();
    return 0;
  }
  return std::max<int64_t>(1, sqlite3_last_insert_rowid(db));
}

std::string text_or_empty(const nlohmann::json& v) { return v.is_string() ? v.get<std::string>() : ""; }

// A pick row as the history request gives it (`rbx1 history --json`); the one SELECT behind query() and pick().
constexpr const char* kPickSelect =
    "SELECT p.id, p.job, p.ts, p.class, p.match_score, p.grip_opening_cm, p.grip_angle_deg, p.place, p.phases_ms, "
    "p.cycle_ms, p.outcome, p.reason, p.attempt, p.scan, s.image FROM picks p LEFT JOIN scans s ON s.id = p.scan";

nlohmann::json read_picks(Stmt& st, std::string& error) {
  static const char* kNames[] = {"id",       "job",       "ts",      "class",   "match_score",
                                 "grip_opening_cm", "grip_angle_deg", "place", "phases_ms", "cycle_ms",
                                 "outcome",  "reason",    "attempt", "scan",    "image"};
  nlohmann::json rows = nlohmann::json::array();
  int rc;
  while ((rc = st.step()) == SQLITE_ROW) {
    nlohmann::json j;
    for (int i = 0; i < 15; ++i) j[kNames[i]] = st.column(i);
    j["phases_ms"] = nlohmann::json::parse(text_or_empty(j["phases_ms"]), nullptr, false);
    if (j["phases_ms"].is_discarded()) j["phases_ms"] = nlohmann::json::object();
    j["image"] = j["image"].is_string();
    rows.push_back(std::move(j));
  }
  if (rc != SQLITE_DONE) error = st.error();
  return rows;
}

}  // namespace

void parse_history_config(config::Section s, HistoryConfig& out) {
  out.max_mb = s.number("max_mb", out.max_mb, 0, 1e6);
  s.reject_unknown();
}

std::unique_ptr<History> History::open(const std::string& dir, const HistoryConfig& config, std::string& error) {
  std::unique_ptr<History> h(new History);
  h->dir_ = dir;
  h->path_ = dir + "/" + kHistoryFile;
  h->config_ = config;
  std::error_code ec;
  fs::create_directories(dir + "/" + kScansDir, ec);
  if (ec) {
    error = dir + "/" + kScansDir + ": cannot create the folder: " + ec.message();
    return nullptr;
  }
  const std::string what_to_do = "; the history is never replaced: move the file aside (mv " + h->path_ + " " +
                                 h->path_ + ".bad) and start rbx1d again to begin a new one";
  if (sqlite3_open_v2(h->path_.c_str(), &h->db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    error = h->path_ + ": cannot open the history database: " + (h->db_ ? sqlite3_errmsg(h->db_) : "out of memory") +
            what_to_do;
    return nullptr;
  }
  sqlite3_busy_timeout(h->db_, 2000);
  // WAL: a writer killed mid-transaction leaves the last commit intact; synchronous=NORMAL loses no commit to a
  // killed process (only to a power cut, and then whole transactions, never half rows).
  std::string e;
  {
    Stmt check(h->db_, "PRAGMA quick_check");
    bool ok = check.ok() && check.step() == SQLITE_ROW && check.column(0) == "ok";
    if (!ok) e = check.ok() ? "failed its integrity check" : check.error();
  }
  if (e.empty() && h->exec("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;", e)) h->exec(kSchema, e);
  if (!e.empty()) {
    error = h->path_ + ": the history database is unreadable (" + e + ")" + what_to_do;
    return nullptr;
  }
  {
    Stmt st(h->db_, "UPDATE jobs SET outcome = 'interrupted', ended = ? WHERE outcome = 'running'");
    st.bind(1, iso_now());
    if (!run_write(h->db_, st, error)) {
      error = h->path_ + ": " + error + what_to_do;
      return nullptr;
    }
    h->interrupted_ = sqlite3_changes(h->db_);
  }
  for (const auto& entry : fs::directory_iterator(dir + "/" + kScansDir, ec))
    if (entry.is_regular_file(ec)) h->image_bytes_ += int64_t(entry.file_size(ec));
  return h;
}

History::~History() { sqlite3_close(db_); }

bool History::exec(const char* sql, std::string& error) {
  char* msg = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &msg) == SQLITE_OK) return true;
  error = msg ? msg : sqlite3_errmsg(db_);
  sqlite3_free(msg);
  return false;
}

int64_t History::begin_job(const std::string& kind, const nlohmann::json& recipe, std::string& error) {
  std::lock_guard lock(mu_);
  Stmt st(db_, "INSERT INTO jobs(kind, recipe, started, outcome) VALUES(?, ?, ?, 'running')");
  st.bind(1, kind);
  st.bind(2, recipe.dump());
  st.bind(3, iso_now());
  return run_write(db_, st, error);
}

bool History::end_job(int64_t job, const std::string& outcome, const nlohmann::json& summary, std::string& error) {
  std::lock_guard lock(mu_);
  Stmt st(db_, "UPDATE jobs SET outcome = ?, ended = ?, summary = ? WHERE id = ?");
  st.bind(1, outcome);
  st.bind(2, iso_now());
  st.bind(3, summary.dump());
  st.bind(4, job);
  return run_write(db_, st, error) != 0;
}

int64_t History::add_scan(int64_t job, int objects, const std::vector<unsigned char>& jpeg, std::string& error) {
  std::lock_guard lock(mu_);
  int64_t id;
  {
    Stmt st(db_, "INSERT INTO scans(job, ts, objects) VALUES(?, ?, ?)");
    st.bind(1, job);
    st.bind(2, iso_now());
    st.bind(3, int64_t(objects));
    if (!(id = run_write(db_, st, error))) return 0;
  }
  if (jpeg.empty() || config_.max_mb <= 0) return id;
  // The row first, the image after: a kill between leaves a scan without an image, never an image without a row.
  std::string name = std::to_string(id) + ".jpg";
  if (!write_file_atomic(dir_ + "/" + kScansDir + "/" + name, std::string(jpeg.begin(), jpeg.end()), error))
    return id;  // the row stands; the image is lost (error says why)
  Stmt st(db_, "UPDATE scans SET image = ? WHERE id = ?");
  st.bind(1, name);
  st.bind(2, id);
  run_write(db_, st, error);
  image_bytes_ += int64_t(jpeg.size());
  prune_images();
  return id;
}

void History::prune_images() {
  // Oldest first: the images are named by their scan id, which only grows.
  const int64_t budget = int64_t(config_.max_mb * 1024 * 1024);
  if (image_bytes_ <= budget) return;
  std::vector<std::pair<int64_t, fs::path>> images;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir_ + "/" + kScansDir, ec)) {
    const auto& p = entry.path();
    if (p.extension() == ".jpg") images.push_back({std::atoll(p.stem().c_str()), p});
  }
  std::sort(images.begin(), images.end());
  for (const auto& [id, p] : images) {
    if (image_bytes_ <= budget) break;
    int64_t size = int64_t(fs::file_size(p, ec));
    if (ec || !fs::remove(p, ec)) continue;
    image_bytes_ -= size;
    Stmt st(db_, "UPDATE scans SET image = NULL WHERE id = ?");
    st.bind(1, id);
    st.step();
  }
}

int64_t History::add_pick(const PickRow& r, std::string& error) {
  std::lock_guard lock(mu_);
  Stmt st(db_,
          "INSERT INTO picks(job, ts, class, match_score, grip_opening_cm, grip_angle_deg, place, phases_ms, "
          "cycle_ms, outcome, reason, attempt, scan) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  st.bind(1, r.job);
  st.bind(2, iso_now());
  st.bind(3, r.cls);
  st.bind(4, r.match_score);
  st.bind(5, r.grip_opening_cm);
  st.bind(6, r.grip_angle_deg);
  st.bind(7, r.place);
  st.bind(8, r.phases_ms.dump());
  st.bind(9, std::optional<double>(r.cycle_ms));
  st.bind(10, r.outcome);
  st.bind(11, r.reason);
  st.bind(12, int64_t(r.attempt));
  if (r.scan) st.bind(13, *r.scan);
  else st.bind_null(13);
  return run_write(db_, st, error);
}

nlohmann::json History::query(const Query& q, std::string& error) {
  std::lock_guard lock(mu_);
  nlohmann::json out{{"jobs", nlohmann::json::array()}, {"picks", nlohmann::json::array()}};
  {
    Stmt st(db_,
            "SELECT id, kind, recipe, started, ended, outcome, summary FROM jobs WHERE started >= ? AND (? = 0 OR "
            "id = ?) ORDER BY id DESC LIMIT ?");
    st.bind(1, q.since);
    st.bind(2, q.job);
    st.bind(3, q.job);
    st.bind(4, int64_t(q.limit));
    int rc;
    while ((rc = st.step()) == SQLITE_ROW) {
      nlohmann::json j{{"id", st.column(0)}, {"kind", st.column(1)}, {"started", st.column(3)},
                       {"ended", st.column(4)}, {"outcome", st.column(5)}};
      j["recipe"] = nlohmann::json::parse(text_or_empty(st.column(2)), nullptr, false);
      j["summary"] = nlohmann::json::parse(text_or_empty(st.column(6)), nullptr, false);
      for (const char* k : {"recipe", "summary"})
        if (j[k].is_discarded()) j[k] = nullptr;
      out["jobs"].push_back(std::move(j));
    }
    if (rc != SQLITE_DONE) error = st.error();
  }
  const std::string sql =
      std::string(kPickSelect) + " WHERE p.ts >= ? AND (? = 0 OR p.job = ?) ORDER BY p.id DESC LIMIT ?";
  Stmt st(db_, sql.c_str());
  st.bind(1, q.since);
  st.bind(2, q.job);
  st.bind(3, q.job);
  st.bind(4, int64_t(q.limit));
  out["picks"] = read_picks(st, error);
  return out;
}

nlohmann::json History::pick(int64_t id, std::string& error) {
  std::lock_guard lock(mu_);
  Stmt st(db_, (std::string(kPickSelect) + " WHERE p.id = ?").c_str());
  st.bind(1, id);
  nlohmann::json rows = read_picks(st, error);
  return rows.empty() ? nlohmann::json() : rows[0];
}

std::string History::picks_csv(const nlohmann::json& picks) {
  static const char* kColumns[] = {"id",    "job",     "ts",       "class",   "match_score", "grip_opening_cm",
                                   "grip_angle_deg", "place", "cycle_ms", "outcome", "reason", "attempt", "scan"};
  std::string out;
  for (const char* c : kColumns) out += std::string(out.empty() ? "" : ",") + c;
  out += "\n";
  for (const auto& p : picks) {
    std::string line;
    for (const char* c : kColumns) {
      const auto& v = p.value(c, nlohmann::json(nullptr));
      std::string cell = v.is_null() ? "" : v.is_string() ? v.get<std::string>() : v.dump();
      if (cell.find_first_of(",\"\n") != std::string::npos) {
        std::string q = "\"";
        for (char ch : cell) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
        cell = q + "\"";
      }
      line += (c == kColumns[0] ? "" : ",") + cell;
    }
    out += line + "\n";
  }
  return out;
}

std::string History::scan_path(int64_t scan) const {
  std::string p = dir_ + "/" + kScansDir + "/" + std::to_string(scan) + ".jpg";
  std::error_code ec;
  return fs::exists(p, ec) ? p : "";
}

int64_t History::image_bytes() const {
  std::lock_guard lock(mu_);
  return image_bytes_;
}

}  // namespace rbx1::history
