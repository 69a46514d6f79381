// history_test.cpp - the history database: rows and queries, interrupted jobs, a corrupt file refused and left
// alone, the image budget, and a writer killed with SIGKILL mid-write (no half row, no committed row lost).
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "history.hpp"

namespace fs = std::filesystem;
using rbx1::history::History;
using rbx1::history::HistoryConfig;
using rbx1::history::PickRow;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/rbx1-history-XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string str() const { return path.string(); }
};

PickRow bolt(int64_t job, int attempt) {
  PickRow r;
  r.job = job;
  r.cls = "bolt";
  r.match_score = 0.97;
  r.grip_opening_cm = 0.5;
  r.grip_angle_deg = -50;
  r.place = "tray";
  r.phases_ms = {{"plan", 3}, {"move", 8200}, {"check", 900}};
  r.cycle_ms = 9103;
  r.outcome = "picked";
  r.attempt = attempt;
  return r;
}

std::unique_ptr<History> open_ok(const TempDir& d, HistoryConfig c = {}) {
  std::string error;
  auto h = History::open(d.str(), c, error);
  EXPECT_TRUE(h) << error;
  return h;
}

std::string read_all(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

TEST(History, JobsPicksAndScansComeBackNewestFirst) {
  TempDir d;
  auto h = open_ok(d);
  std::string error;
  int64_t job = h->begin_job("sort", {{"bolt", "tray"}}, error);
  ASSERT_GT(job, 0) << error;
  int64_t scan = h->add_scan(job, 3, {0xff, 0xd8, 0xff, 0xd9}, error);
  ASSERT_GT(scan, 0) << error;
  auto row = bolt(job, 1);
  row.scan = scan;
  int64_t first = h->add_pick(row, error);
  ASSERT_GT(first, 0) << error;
  PickRow skipped;
  skipped.job = job;
  skipped.cls = "nut";
  skipped.outcome = "skipped";
  skipped.reason = "infeasible_grip: too_wide";
  ASSERT_GT(h->add_pick(skipped, error), 0) << error;
  ASSERT_TRUE(h->end_job(job, "done", {{"picked", 1}}, error)) << error;

  auto j = h->query({}, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_EQ(j["jobs"].size(), 1u);
  EXPECT_EQ(j["jobs"][0]["outcome"], "done");
  EXPECT_EQ(j["jobs"][0]["recipe"]["bolt"], "tray");
  EXPECT_EQ(j["jobs"][0]["summary"]["picked"], 1);
  ASSERT_EQ(j["picks"].size(), 2u);
  EXPECT_EQ(j["picks"][0]["reason"], "infeasible_grip: too_wide");
  EXPECT_TRUE(j["picks"][0]["match_score"].is_null());
  EXPECT_EQ(j["picks"][1]["class"], "bolt");
  EXPECT_EQ(j["picks"][1]["phases_ms"]["move"], 8200);
  EXPECT_EQ(j["picks"][1]["scan"], scan);
  EXPECT_EQ(j["picks"][1]["image"], true);
  EXPECT_EQ(read_all(h->scan_path(scan)).size(), 4u);
  // One row by its id (the bus's picks topic) is the query's row, field for field.
  EXPECT_EQ(h->pick(first, error), j["picks"][1]);
  EXPECT_TRUE(h->pick(first + 100, error).is_null());
  EXPECT_TRUE(error.empty()) << error;

  // Filters: another job's rows and a future --since leave nothing.
  EXPECT_EQ(h->query({"", job + 1, 10}, error)["picks"].size(), 0u);
  EXPECT_EQ(h->query({"2999-01-01", 0, 10}, error)["jobs"].size(), 0u);
  EXPECT_EQ(h->query({"2000-01-01", job, 1}, error)["picks"].size(), 1u);

  std::string csv = History::picks_csv(j["picks"]);
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "id,job,ts,class,match_score,grip_opening_cm,grip_angle_deg,place,cycle_ms,outcome,reason,attempt,scan");
  EXPECT_NE(csv.find(",nut,,,,,0.0,skipped,infeasible_grip: too_wide,1,\n"), std::string::npos) << csv;
}

TEST(History, JobsLeftRunningAreMarkedInterruptedAtTheNextOpen) {
  TempDir d;
  int64_t job;
  {
    auto h = open_ok(d);
    std::string error;
    job = h->begin_job("clear", {{"place", "bin"}}, error);
    ASSERT_GT(job, 0);
  }
  auto h = open_ok(d);
  EXPECT_EQ(h->interrupted_at_open(), 1);
  std::string error;
  auto j = h->query({}, error);
  EXPECT_EQ(j["jobs"][0]["outcome"], "interrupted");
  EXPECT_TRUE(j["jobs"][0]["ended"].is_string());
  EXPECT_EQ(open_ok(d)->interrupted_at_open(), 0);  // once
}

TEST(History, ACorruptDatabaseIsRefusedNamedAndLeftAlone) {
  TempDir d;
  fs::path db = d.path / "history.sqlite";
  std::string junk(8192, 'x');
  std::ofstream(db, std::ios::binary) << junk;
  std::string error;
  EXPECT_FALSE(History::open(d.str(), {}, error));
  EXPECT_NE(error.find(db.string() + ": the history database is unreadable"), std::string::npos) << error;
  EXPECT_NE(error.find("move the file aside"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);  // one line
  EXPECT_EQ(read_all(db), junk);                   // never replaced
}

TEST(History, OldestImagesGoFirstBeyondTheBudgetAndTheRowsStay) {
  TempDir d;
  HistoryConfig c;
  c.max_mb = 2500.0 / (1024 * 1024);  // room for two 1000-byte images
  auto h = open_ok(d, c);
  std::string error;
  std::vector<int64_t> scans;
  for (int i = 0; i < 5; ++i) scans.push_back(h->add_scan(1, 1, std::vector<unsigned char>(1000, 0xAB), error));
  EXPECT_EQ(h->image_bytes(), 2000);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(h->scan_path(scans[i]), "") << i;
  for (int i = 3; i < 5; ++i) EXPECT_NE(h->scan_path(scans[i]), "") << i;
  int files = 0;
  for (auto& e : fs::directory_iterator(d.path / "scans")) files += e.path().extension() == ".jpg";
  EXPECT_EQ(files, 2);
  // Reopened, the budget counts what is on disk.
  h.reset();
  EXPECT_EQ(open_ok(d, c)->image_bytes(), 2000);
}

TEST(History, AWriterKilledMidWriteLosesNoCommittedRowAndLeavesNoHalfRow) {
  TempDir d;
  open_ok(d);  // schema in place before the child starts
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The child: one job, then rows as fast as it can, reporting each committed row's id on the pipe.
    close(fds[0]);
    std::string error;
    auto h = History::open(d.str(), {}, error);
    if (!h) _exit(3);
    int64_t job = h->begin_job("sort", {{"bolt", "tray"}}, error);
    for (int i = 1;; ++i) {
      int64_t id = h->add_pick(bolt(job, i), error);
      if (!id || write(fds[1], &id, sizeof id) != sizeof id) _exit(4);
    }
  }
  close(fds[1]);
  int64_t last = 0, id;
  auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(300);
  while (std::chrono::steady_clock::now() < until && read(fds[0], &id, sizeof id) == sizeof id) last = id;
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  while (read(fds[0], &id, sizeof id) == sizeof id) last = id;  // rows committed before the kill
  close(fds[0]);
  ASSERT_TRUE(WIFSIGNALED(status)) << status;
  ASSERT_GT(last, 5);

  auto h = open_ok(d);
  EXPECT_EQ(h->interrupted_at_open(), 1);
  std::string error;
  auto j = h->query({"", 0, 1000000}, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_GE(int64_t(j["picks"].size()), last);  // every reported row is there
  ASSERT_EQ(j["picks"][0]["id"], int64_t(j["picks"].size()));  // ids 1..N without gaps
  for (const auto& p : j["picks"]) {  // and each is whole
    ASSERT_EQ(p["class"], "bolt");
    ASSERT_EQ(p["place"], "tray");
    ASSERT_EQ(p["phases_ms"]["check"], 900);
    ASSERT_EQ(p["attempt"], p["id"]);
    ASSERT_EQ(p["outcome"], "picked");
  }
  std::printf("killed writer: %ld rows reported committed, %zu in the database\n", long(last), j["picks"].size());
}
