// serial_port_test.cpp - raw mode, custom baud, HUPCL and exclusivity on a pty; config parsing.
#include "serial_port.hpp"

#include <cstdio>
#include <cstring>
#include <pty.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "link.hpp"

using namespace rbx1::link;

namespace {
struct Pty {
  int master = -1;
  std::string path;
  Pty() {
    int slave;
    char name[128];
    if (openpty(&master, &slave, name, nullptr, nullptr) == 0) {
      path = name;
      ::close(slave);
    }
  }
  ~Pty() { ::close(master); }
};
}  // namespace

TEST(SerialPort, RawModeNoHangupExclusiveAt250000) {
  Pty pty;
  ASSERT_FALSE(pty.path.empty());
  for (int baud : {115200, 230400, 250000}) {
    std::string error;
    int fd = open_serial(pty.path, baud, error);
    ASSERT_GE(fd, 0) << error;
    EXPECT_EQ(serial_baud(fd), baud);
    termios t{};
    ASSERT_EQ(tcgetattr(fd, &t), 0);
    EXPECT_EQ(t.c_cflag & HUPCL, 0u);
    EXPECT_EQ(t.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
    EXPECT_EQ(t.c_lflag & (ICANON | ECHO | ISIG), 0u);
    EXPECT_EQ(t.c_oflag & OPOST, 0u);
    int excl = 0;
    ASSERT_EQ(ioctl(fd, TIOCGEXCL, &excl), 0);
    EXPECT_EQ(excl, 1);
    ::close(fd);
  }
}

TEST(SerialPort, SecondOpenIsRefused) {
  Pty pty;
  std::string error;
  int fd = open_serial(pty.path, 115200, error);
  ASSERT_GE(fd, 0) << error;
  EXPECT_EQ(open_serial(pty.path, 115200, error), -EBUSY);  // also for root, whom TIOCEXCL lets through
  EXPECT_EQ(error, pty.path + ": in use by another program");
  ::close(fd);
  fd = open_serial(pty.path, 115200, error);
  EXPECT_GE(fd, 0) << error;
  ::close(fd);
}

TEST(SerialPort, BytesPassUnchanged) {
  Pty pty;
  std::string error;
  int fd = open_serial(pty.path, 115200, error);
  ASSERT_GE(fd, 0) << error;
  const uint8_t bytes[] = {0xA5, 0x0D, 0x0A, 0x03, 0x11, 0x13, 0x7F, 0x00};
  ASSERT_EQ(write(pty.master, bytes, sizeof bytes), static_cast<ssize_t>(sizeof bytes));
  uint8_t got[16];
  ssize_t n = 0;
  for (int i = 0; i < 50 && n < static_cast<ssize_t>(sizeof bytes); ++i) {
    ssize_t r = read(fd, got + n, sizeof got - n);
    if (r > 0) n += r;
  }
  ASSERT_EQ(n, static_cast<ssize_t>(sizeof bytes));
  EXPECT_EQ(std::memcmp(got, bytes, sizeof bytes), 0);
  ::close(fd);
}

TEST(SerialPort, RefusesOtherBauds) {
  Pty pty;
  std::string error;
  EXPECT_EQ(open_serial(pty.path, 9600, error), -EINVAL);
  EXPECT_NE(error.find("unsupported baud 9600"), std::string::npos) << error;
  std::string file = "/tmp/rbx1-not-a-tty-" + std::to_string(getpid());
  FILE* f = std::fopen(file.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fclose(f);
  EXPECT_EQ(open_serial(file, 115200, error), -ENOTTY);
  EXPECT_EQ(error, file + ": not a serial device (Inappropriate ioctl for device)");
  std::remove(file.c_str());
}

TEST(LinkConfig, ParsesAndChecksTheLinkTable) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text(
      "[link]\nport = \"/dev/rbx1\"\nbaud = 250000\ntimeout_ms = 150\nretries = 3\nheartbeat_ms = 300\n"
      "boot_wait_ms = 0\n", errors);
  rbx1::config::Section root(&t, "", errors);
  LinkConfig c;
  parse_link_config(root.section("link"), c);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_EQ(c.port, "/dev/rbx1");
  EXPECT_EQ(c.baud, 250000);
  EXPECT_EQ(c.timeout_ms, 150);
  EXPECT_EQ(c.retries, 3);
  EXPECT_EQ(c.heartbeat_ms, 300);
  EXPECT_EQ(c.boot_wait_ms, 0);
}

TEST(LinkConfig, DefaultsAndErrorsNameTheKey) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text("[link]\nbaud = 9600\nretries = 99\nspeed = 1\n", errors);
  rbx1::config::Section root(&t, "", errors);
  LinkConfig c;
  parse_link_config(root.section("link"), c);
  ASSERT_EQ(errors.messages().size(), 3u) << errors.joined();
  EXPECT_EQ(errors.messages()[0], "link.baud: must be 115200, 230400 or 250000, got 9600");
  EXPECT_EQ(errors.messages()[1].rfind("link.retries: must be within [0, 20]", 0), 0u);
  EXPECT_EQ(errors.messages()[2], "link.speed: unknown key");
  EXPECT_EQ(c.baud, 115200);
  EXPECT_EQ(c.retries, 5);
  EXPECT_EQ(c.timeout_ms, 100);
}
