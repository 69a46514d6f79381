// link_simfw_test.cpp - Link against the simulated firmware (build/bin/rbx1-simfw): handshake, moves executed
// exactly once with and without injected byte corruption and loss (one at a time and windowed streams), e-stop
// mid-move, round-trip time.
#include "link.hpp"
#include "rbx1_window.h"

#include <algorithm>
#include <cstdlib>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

using namespace std::chrono;
using rbx1::link::Link;

namespace {

// The simulator to run: $RBX1_SIMFW, else build/bin/rbx1-simfw.
const char* simfw() {
  const char* env = getenv("RBX1_SIMFW");
  return env && *env ? env : RBX1_SIMFW;
}

// Runs rbx1-simfw with extra arguments and reads the pty path from its first stdout line.
class SimFw {
 public:
  explicit SimFw(const std::vector<std::string>& args) {
    int out[2];
    if (pipe(out) != 0) return;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], 1);
      ::close(out[0]);
      ::close(out[1]);
      std::vector<char*> argv{const_cast<char*>(simfw())};
      for (auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(simfw(), argv.data());
      _exit(127);
    }
    ::close(out[1]);
    out_ = out[0];
    std::string line;
    auto t0 = steady_clock::now();
    while (steady_clock::now() - t0 < seconds(5)) {
      pollfd p{out_, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char c;
      if (read(out_, &c, 1) != 1) break;
      if (c == '\n') {
        pty_ = line;
        break;
      }
      line += c;
    }
  }
  ~SimFw() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status;
      waitpid(pid_, &status, 0);
    }
    if (out_ >= 0) ::close(out_);
  }
  const std::string& pty() const { return pty_; }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string pty_;
};

// The build makes rbx1-simfw before this test: missing means a broken build, not a reason to pass.
#define REQUIRE_SIMFW() \
  if (access(simfw(), X_OK) != 0) FAIL() << simfw() << " is not built: run make first"

// Homes by declaration, enables, sends n small moves (retrying QUEUE_FULL, which executes nothing), and waits
// for moves_done to reach n. Returns the targets sent.
std::vector<std::array<int32_t, RBX1_JOINTS>> run_moves(Link& link, int n) {
  std::vector<std::array<int32_t, RBX1_JOINTS>> sent;
  int32_t zero[RBX1_JOINTS] = {0, 0, 0, 0, 0, 0};
  rbx1_set_position_resp sp{};
  EXPECT_EQ(link.set_position(zero, sp), 0);
  EXPECT_EQ(sp.status, RBX1_OK);
  rbx1_enable_resp en{};
  EXPECT_EQ(link.enable(true, en), 0);
  EXPECT_EQ(en.status, RBX1_OK);
  for (int i = 0; i < n; ++i) {
    rbx1_move_req m{};
    for (int j = 0; j < RBX1_JOINTS; ++j) m.target[j] = (i + 1) * 10 * (j % 2 ? -1 : 1) + j;
    m.duration_ms = 0;
    for (int tries = 0; tries < 200; ++tries) {
      rbx1_move_resp r{};
      int rc = link.move(m, r);
      EXPECT_EQ(rc, 0) << "move " << i;
      if (rc < 0) return sent;
      if (r.status == RBX1_QUEUE_FULL) {
        std::this_thread::sleep_for(milliseconds(10));
        continue;
      }
      EXPECT_EQ(r.status, RBX1_OK) << rbx1_status_name(r.status);
      break;
    }
    std::array<int32_t, RBX1_JOINTS> t;
    std::copy(std::begin(m.target), std::end(m.target), t.begin());
    sent.push_back(t);
  }
  rbx1_status_resp s{};
  auto t0 = steady_clock::now();
  do {
    std::this_thread::sleep_for(milliseconds(20));
    EXPECT_EQ(link.status(s), 0);
  } while (s.moves_done < n && steady_clock::now() - t0 < seconds(20));
  EXPECT_EQ(s.moves_done, n);
  EXPECT_EQ(s.position[0], sent.back()[0]);
  EXPECT_EQ(s.position[5], sent.back()[5]);
  return sent;
}

// The --log-moves lines: one per completed queue entry.
std::vector<std::string> log_lines(const std::string& file) {
  std::vector<std::string> lines;
  std::ifstream in(file);
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) lines.push_back(l);
  return lines;
}

std::string target_text(const std::array<int32_t, RBX1_JOINTS>& t) {
  std::string s = "\"target\":[";
  for (int j = 0; j < RBX1_JOINTS; ++j) s += (j ? "," : "") + std::to_string(t[j]);
  return s + "]";
}

// Every move sent is in the firmware's --log-moves file, once, in the order sent: nothing lost, nothing run twice.
void expect_logged_once_in_order(const std::string& log, const std::vector<std::array<int32_t, RBX1_JOINTS>>& sent) {
  auto lines = log_lines(log);
  ASSERT_EQ(lines.size(), sent.size());
  for (size_t i = 0; i < sent.size(); ++i) EXPECT_NE(lines[i].find(target_text(sent[i])), std::string::npos) << i;
}

// The link's counters of a fault run, printed for the log (figures, not checks).
void print_fault_stats(const char* run, const rbx1::link::LinkStats& st) {
  std::printf("%s: %llu requests, %llu retransmissions, %llu NAKs, %llu rejected, %llu stale\n", run,
              (unsigned long long)st.requests, (unsigned long long)st.retransmissions, (unsigned long long)st.naks,
              (unsigned long long)st.rejected, (unsigned long long)st.stale);
}

std::string temp_file(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (name + "-" + std::to_string(getpid()))).string();
}

}  // namespace

TEST(LinkSimFw, HandshakeAndStatus) {
  REQUIRE_SIMFW();
  SimFw sim({});
  ASSERT_FALSE(sim.pty().empty());
  Link link;
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  EXPECT_EQ(link.firmware().joints, 6);
  EXPECT_TRUE(link.firmware().capabilities & RBX1_CAP_SIMULATED);
  rbx1_status_resp s{};
  ASSERT_EQ(link.status(s), 0);
  EXPECT_EQ(s.status, RBX1_OK);
  EXPECT_EQ(s.state, RBX1_STATE_IDLE);
  EXPECT_EQ(s.homed, 0);
}

TEST(LinkSimFw, MovesExecuteExactlyOnce) {
  REQUIRE_SIMFW();
  std::string log = temp_file("rbx1-moves");
  std::filesystem::remove(log);
  SimFw sim({"--log-moves", log});
  Link link;
  link.set_timing(1000, 5);  // no faults injected: not one retransmission, even on a loaded machine
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  auto sent = run_moves(link, 12);
  expect_logged_once_in_order(log, sent);
  EXPECT_EQ(link.stats().retransmissions, 0u);
  std::filesystem::remove(log);
}

TEST(LinkSimFw, InjectedFaultsLoseAndRepeatNothing) {
  REQUIRE_SIMFW();
  std::string log = temp_file("rbx1-moves-faults");
  std::filesystem::remove(log);
  SimFw sim({"--log-moves", log, "--corrupt", "0.003", "--drop", "0.003", "--seed", "11"});
  Link link;
  link.set_timing(150, 8);  // headroom for a loaded machine; the faults are still recovered by retransmission
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  auto sent = run_moves(link, 30);
  expect_logged_once_in_order(log, sent);
  auto st = link.stats();
  EXPECT_GT(st.retransmissions, 0u) << "the fault injection did not hit a single exchange";
  EXPECT_EQ(st.link_down, 0u);
  print_fault_stats("fault run", st);
  std::filesystem::remove(log);
}

// MOVE streams with the window in flight, each no longer than the queue's room (so none is refused QUEUE_FULL),
// under 1 % byte corruption both ways: every move runs once, in order.
TEST(LinkSimFw, WindowedStreamsUnderCorruptionLoseAndRepeatNothing) {
  REQUIRE_SIMFW();
  std::string log = temp_file("rbx1-moves-window");
  std::filesystem::remove(log);
  SimFw sim({"--log-moves", log, "--corrupt", "0.01", "--seed", "5"});
  Link link;
  link.set_timing(150, 10);
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  EXPECT_EQ(link.window(), RBX1_WINDOW);
  int32_t zero[RBX1_JOINTS] = {0, 0, 0, 0, 0, 0};
  rbx1_set_position_resp sp{};
  ASSERT_EQ(link.set_position(zero, sp), 0);
  rbx1_enable_resp en{};
  ASSERT_EQ(link.enable(true, en), 0);
  const int n = 120;
  std::vector<std::array<int32_t, RBX1_JOINTS>> sent;
  auto t0 = steady_clock::now();
  while (int(sent.size()) < n && steady_clock::now() - t0 < seconds(60)) {
    rbx1_status_resp s{};
    ASSERT_EQ(link.status(s), 0);
    int batch = std::min<int>(s.queue_free, n - int(sent.size()));
    if (batch == 0) {
      std::this_thread::sleep_for(milliseconds(5));
      continue;
    }
    std::vector<rbx1_move_req> reqs(batch);
    for (int i = 0; i < batch; ++i) {
      int k = int(sent.size()) + i;
      for (int j = 0; j < RBX1_JOINTS; ++j) reqs[i].target[j] = (k + 1) * 3 * (j % 2 ? -1 : 1) + j;
    }
    std::vector<rbx1_move_resp> out;
    std::vector<bool> answered;
    ASSERT_EQ(link.move_stream(reqs, out, answered), 0);
    for (int i = 0; i < batch; ++i) {
      ASSERT_EQ(out[i].status, RBX1_OK) << rbx1_status_name(out[i].status);
      std::array<int32_t, RBX1_JOINTS> t;
      std::copy(std::begin(reqs[i].target), std::end(reqs[i].target), t.begin());
      sent.push_back(t);
    }
  }
  ASSERT_EQ(int(sent.size()), n);
  rbx1_status_resp s{};
  do {
    std::this_thread::sleep_for(milliseconds(20));
    ASSERT_EQ(link.status(s), 0);
  } while (s.moves_done < n && steady_clock::now() - t0 < seconds(60));
  EXPECT_EQ(s.moves_done, n);
  EXPECT_EQ(s.moves_accepted, n);
  expect_logged_once_in_order(log, sent);
  auto st = link.stats();
  EXPECT_GT(st.retransmissions, 0u) << "1 % corruption did not hit a single frame";
  EXPECT_EQ(st.link_down, 0u);
  print_fault_stats("windowed fault run", st);
  std::filesystem::remove(log);
}

TEST(LinkSimFw, EstopStopsAMoveInProgress) {
  REQUIRE_SIMFW();
  SimFw sim({});
  Link link;
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  int32_t zero[RBX1_JOINTS] = {0, 0, 0, 0, 0, 0};
  rbx1_set_position_resp sp{};
  rbx1_enable_resp en{};
  ASSERT_EQ(link.set_position(zero, sp), 0);
  ASSERT_EQ(link.enable(true, en), 0);
  rbx1_move_req m{{20000, 0, 0, 0, 0, 0}, 3000};
  rbx1_move_resp mr{};
  ASSERT_EQ(link.move(m, mr), 0);
  ASSERT_EQ(mr.status, RBX1_OK);
  std::this_thread::sleep_for(milliseconds(300));
  rbx1_estop_resp e{};
  ASSERT_EQ(link.estop(e), 0);
  EXPECT_EQ(e.status, RBX1_OK);
  rbx1_status_resp a{}, b{};
  ASSERT_EQ(link.status(a), 0);
  std::this_thread::sleep_for(milliseconds(100));
  ASSERT_EQ(link.status(b), 0);
  EXPECT_EQ(a.state, RBX1_STATE_FAULT);
  EXPECT_TRUE(a.faults & RBX1_FAULT_ESTOP_COMMAND);
  EXPECT_GT(a.position[0], 0);
  EXPECT_LT(a.position[0], 20000);
  EXPECT_EQ(a.position[0], b.position[0]);  // no pulse after the e-stop
  ASSERT_EQ(link.move(m, mr), 0);
  EXPECT_NE(mr.status, RBX1_OK);  // latched until CLEAR_FAULT
}

// 300 STATUS exchanges in a row over the pty, each answered once. The round trip is printed (and recorded) as a
// figure, not checked: a timed assertion fails on a loaded machine (a 22.6 ms median at load 24 against the 20 ms
// it once had), and the link's speed is measured by make bench (tools/bench/link-window, daemon-latency).
TEST(LinkSimFw, StatusRoundTrips) {
  REQUIRE_SIMFW();
  SimFw sim({});
  Link link;
  link.set_timing(2000, 5);  // the figure is the median: one answer a loaded machine delays must not end the run
  std::string error;
  ASSERT_EQ(link.open(sim.pty(), 115200, error), 0) << error;
  std::vector<double> us;
  for (int i = 0; i < 300; ++i) {
    rbx1_status_resp s{};
    auto t0 = steady_clock::now();
    ASSERT_EQ(link.status(s), 0);
    us.push_back(duration<double, std::micro>(steady_clock::now() - t0).count());
  }
  std::sort(us.begin(), us.end());
  double mean = 0;
  for (double v : us) mean += v;
  mean /= us.size();
  std::printf("STATUS round trip over the pty: mean %.0f us, median %.0f us, p99 %.0f us (n=%zu)\n", mean,
              us[us.size() / 2], us[us.size() * 99 / 100], us.size());
  RecordProperty("rtt_mean_us", static_cast<int>(mean));
  EXPECT_EQ(link.stats().link_down, 0u);
}
