// test_simfw_pty.cpp - starts rbx1-simfw, opens the pty it prints, and does a HELLO round trip over it.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "rbx1_proto.h"

namespace {

struct Collected {
  std::vector<rbx1_frame> frames;
};

void on_frame(void* ctx, const rbx1_frame* f) { static_cast<Collected*>(ctx)->frames.push_back(*f); }

TEST(SimfwPty, HelloOverThePty) {
  int out[2];
  ASSERT_EQ(pipe(out), 0);
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    execl(RBX1_SIMFW_PATH, RBX1_SIMFW_PATH, "--seed", "3", (char*)nullptr);
    _exit(127);
  }
  close(out[1]);
  std::string path;
  char c;
  pollfd pfd{out[0], POLLIN, 0};
  while (poll(&pfd, 1, 5000) > 0 && read(out[0], &c, 1) == 1 && c != '\n') path += c;
  ASSERT_FALSE(path.empty()) << "no pty path on stdout";

  int fd = open(path.c_str(), O_RDWR | O_NOCTTY);
  ASSERT_GE(fd, 0) << path;
  termios t{};
  tcgetattr(fd, &t);
  cfmakeraw(&t);
  tcsetattr(fd, TCSANOW, &t);

  uint8_t payload[1] = {RBX1_PROTO_VERSION}, frame[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(frame, sizeof(frame), 0, RBX1_MSG_HELLO, payload, 1);
  ASSERT_EQ(write(fd, frame, n), (ssize_t)n);

  Collected got;
  rbx1_decoder dec;
  rbx1_decoder_init(&dec, on_frame, nullptr, &got);
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (got.frames.empty() && std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 100) > 0) {
      uint8_t buf[128];
      ssize_t r = read(fd, buf, sizeof(buf));
      if (r > 0) rbx1_decoder_feed(&dec, buf, (size_t)r);
    }
  }
  close(fd);
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  close(out[0]);

  ASSERT_EQ(got.frames.size(), 1u);
  const rbx1_frame& f = got.frames[0];
  EXPECT_EQ(f.seq, 0);
  EXPECT_EQ(f.type, RBX1_RESPONSE(RBX1_MSG_HELLO));
  rbx1_hello_resp h{};
  ASSERT_EQ(rbx1_hello_resp_unpack(&h, f.payload, f.len), RBX1_OK);
  EXPECT_EQ(h.status, RBX1_OK);
  EXPECT_EQ(h.proto_version, RBX1_PROTO_VERSION);
  EXPECT_EQ(h.joints, 6);
  EXPECT_TRUE(h.capabilities & RBX1_CAP_SIMULATED);
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "SIGTERM must end it with status 0";
}

}  // namespace

namespace {

// A small blocking client of the pty for the interface test below.
struct Client {
  int fd = -1;
  uint8_t seq = 0;
  rbx1_decoder dec{};
  Collected got;
  explicit Client(const std::string& path) {
    fd = open(path.c_str(), O_RDWR | O_NOCTTY);
    termios t{};
    tcgetattr(fd, &t);
    cfmakeraw(&t);
    tcsetattr(fd, TCSANOW, &t);
    rbx1_decoder_init(&dec, on_frame, nullptr, &got);
  }
  ~Client() { close(fd); }
  std::vector<uint8_t> request(uint8_t type, const uint8_t* payload, uint8_t len) {
    uint8_t frame[RBX1_MAX_FRAME];
    size_t n = rbx1_frame_encode(frame, sizeof(frame), seq++, type, payload, len);
    got.frames.clear();
    if (write(fd, frame, n) != (ssize_t)n) return {};
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (got.frames.empty() && std::chrono::steady_clock::now() < deadline) {
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 50) > 0) {
        uint8_t buf[128];
        ssize_t r = read(fd, buf, sizeof(buf));
        if (r > 0) rbx1_decoder_feed(&dec, buf, (size_t)r);
      }
    }
    if (got.frames.empty()) return {};
    const rbx1_frame& f = got.frames[0];
    return std::vector<uint8_t>(f.payload, f.payload + f.len);
  }
};

std::string read_file(const std::string& path) {
  std::string s;
  if (FILE* f = std::fopen(path.c_str(), "r")) {
    char buf[512];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) s.append(buf, n);
    std::fclose(f);
  }
  return s;
}

TEST(SimfwPty, MoveLogControlResetEepromAndQuit) {
  char dir[] = "/tmp/rbx1-simfw-test-XXXXXX";
  ASSERT_NE(mkdtemp(dir), nullptr);
  std::string d = dir, fifo = d + "/ctl", log = d + "/moves.jsonl", eeprom = d + "/eeprom.bin";
  int out[2];
  ASSERT_EQ(pipe(out), 0);
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    dup2(out[1], 1);
    close(out[0]);
    execl(RBX1_SIMFW_PATH, RBX1_SIMFW_PATH, "--control", fifo.c_str(), "--log-moves", log.c_str(), "--eeprom",
          eeprom.c_str(), (char*)nullptr);
    _exit(127);
  }
  close(out[1]);
  std::string path;
  char c;
  pollfd pfd{out[0], POLLIN, 0};
  while (poll(&pfd, 1, 5000) > 0 && read(out[0], &c, 1) == 1 && c != '\n') path += c;
  ASSERT_FALSE(path.empty());
  {
    Client cl(path);
    uint8_t p[RBX1_MAX_PAYLOAD];
    rbx1_enable_req en{1};
    ASSERT_EQ(cl.request(RBX1_MSG_ENABLE, p, rbx1_enable_req_pack(&en, p)).at(0), RBX1_OK);
    rbx1_set_position_req sp{{0, 0, 0, 0, 0, 0}};
    ASSERT_EQ(cl.request(RBX1_MSG_SET_POSITION, p, rbx1_set_position_req_pack(&sp, p)).at(0), RBX1_OK);
    rbx1_move_req mv{{200, -100, 50, 0, 0, 7}, 500};  // longer than its profile (~0.3 s)
    ASSERT_EQ(cl.request(RBX1_MSG_MOVE, p, rbx1_move_req_pack(&mv, p)).at(0), RBX1_OK);
    rbx1_config_set_req cs{0, RBX1_KEY_ACCEL, 4321};
    for (int i = 0; i < 100; i++) {  // CONFIG_SET is BUSY until the move is done
      usleep(20000);
      if (cl.request(RBX1_MSG_CONFIG_SET, p, rbx1_config_set_req_pack(&cs, p)).at(0) == RBX1_OK) break;
    }
    std::string line = read_file(log);
    const std::string fixed = "{\"n\":1,\"kind\":\"move\",\"target\":[200,-100,50,0,0,7],\"start\":[0,0,0,0,0,0],"
                              "\"end\":[200,-100,50,0,0,7],\"duration_ms\":500,\"pulse_us\":0,\"mono_ns\":";
    ASSERT_EQ(line.substr(0, fixed.size()), fixed) << line;
    // mono_ns: CLOCK_MONOTONIC when the entry completed, so between the MOVE and now.
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    long long t = std::stoll(line.substr(fixed.size()));
    EXPECT_LE(t, (long long)now.tv_sec * 1000000000LL + now.tv_nsec) << line;
    EXPECT_GT(t, (long long)now.tv_sec * 1000000000LL + now.tv_nsec - 3000000000LL) << line;
    EXPECT_EQ(line.substr(line.size() - 2), "}\n") << line;
    FILE* ctl = std::fopen(fifo.c_str(), "w");
    ASSERT_NE(ctl, nullptr);
    std::fputs("reset\n", ctl);
    std::fflush(ctl);
    usleep(200000);
    std::vector<uint8_t> st = cl.request(RBX1_MSG_STATUS, nullptr, 0);
    rbx1_status_resp s{};
    ASSERT_EQ(rbx1_status_resp_unpack(&s, st.data(), (uint8_t)st.size()), RBX1_OK);
    EXPECT_EQ(s.homed, 0) << "reset is a power cycle";
    EXPECT_EQ(s.enabled, 0);
    EXPECT_FALSE(s.faults & RBX1_FAULT_EEPROM_DEFAULTS) << "EEPROM kept across the reset";
    rbx1_config_get_req cg{0, RBX1_KEY_ACCEL};
    std::vector<uint8_t> g = cl.request(RBX1_MSG_CONFIG_GET, p, rbx1_config_get_req_pack(&cg, p));
    rbx1_config_get_resp gv{};
    ASSERT_EQ(rbx1_config_get_resp_unpack(&gv, g.data(), (uint8_t)g.size()), RBX1_OK);
    EXPECT_EQ(gv.value, 4321);
    std::fputs("quit\n", ctl);
    std::fclose(ctl);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  close(out[0]);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  std::string img = read_file(eeprom);
  EXPECT_EQ(img.size(), 4096u);
  unlink(fifo.c_str());
  unlink(log.c_str());
  unlink(eeprom.c_str());
  rmdir(dir);
}

}  // namespace
