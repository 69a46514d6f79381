// history_bench.cpp - the history's cost (tools/bench/history): time per pick row written (median, p99) and disk
// per 1,000 picks, without images and with one scan JPEG per pick (as a sort writes them).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "history.hpp"

namespace fs = std::filesystem;
using rbx1::history::History;

namespace {

int64_t bytes_in(const fs::path& dir) {
  int64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) n += int64_t(e.file_size());
  return n;
}

// Writes picks rows (and a scan with jpeg before each when given); prints one JSON line.
int run(const std::string& label, int picks, const std::vector<unsigned char>& jpeg) {
  char tmpl[] = "/tmp/rbx1-history-bench-XXXXXX";
  fs::path dir = mkdtemp(tmpl);
  std::string error;
  std::vector<double> row_us;
  {
    rbx1::history::HistoryConfig c;
    c.max_mb = 1e6;  // keep every image: the figure is the disk they take
    auto h = History::open(dir.string(), c, error);
    if (!h) {
      std::fprintf(stderr, "history-bench: %s\n", error.c_str());
      return 1;
    }
    int64_t job = h->begin_job("sort", {{"rectangle", "tray"}, {"*", "bin"}}, error);
    for (int i = 0; i < picks; ++i) {
      std::optional<int64_t> scan;
      if (!jpeg.empty()) scan = h->add_scan(job, 6, jpeg, error);
      rbx1::history::PickRow r;
      r.job = job;
      r.cls = i % 2 ? "rectangle" : "ellipse";
      r.match_score = 0.93;
      r.grip_opening_cm = 1.87;
      r.grip_angle_deg = -42.5;
      r.place = i % 2 ? "tray" : "bin";
      r.phases_ms = {{"scan", 412.3}, {"plan", 3.1}, {"move", 8123.4}, {"check", 1200.2}};
      r.cycle_ms = 9739.0;
      r.outcome = "picked";
      r.scan = scan;
      auto t = std::chrono::steady_clock::now();
      if (!h->add_pick(r, error)) {
        std::fprintf(stderr, "history-bench: %s\n", error.c_str());
        return 1;
      }
      row_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t).count());
    }
    h->end_job(job, "done", {{"picked", picks}}, error);
  }  // closed: the WAL is checkpointed into the database
  std::sort(row_us.begin(), row_us.end());
  auto pct = [&](double p) { return row_us[std::min(row_us.size() - 1, size_t(p * row_us.size()))]; };
  int64_t db = int64_t(fs::file_size(dir / rbx1::history::kHistoryFile));
  int64_t all = bytes_in(dir);
  std::printf("{\"case\": \"%s\", \"picks\": %d, \"row_us_median\": %.1f, \"row_us_p99\": %.1f, \"row_us_max\": %.1f, "
              "\"db_bytes_per_1000\": %.0f, \"disk_bytes_per_1000\": %.0f, \"jpeg_bytes\": %zu}\n",
              label.c_str(), picks, pct(0.5), pct(0.99), row_us.back(), db * 1000.0 / picks, all * 1000.0 / picks,
              jpeg.size());
  fs::remove_all(dir);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: history-bench SCAN.jpg [PICKS]\n");
    return 2;
  }
  std::ifstream f(argv[1], std::ios::binary);
  std::vector<unsigned char> jpeg((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (jpeg.empty()) {
    std::fprintf(stderr, "history-bench: %s: unreadable or empty\n", argv[1]);
    return 2;
  }
  int picks = argc > 2 ? std::atoi(argv[2]) : 2000;
  return run("rows only", picks, {}) || run("rows and one scan JPEG per pick", picks, jpeg);
}
