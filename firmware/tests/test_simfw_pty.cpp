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
