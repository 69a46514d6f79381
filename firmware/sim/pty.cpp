// pty.cpp - opens the pseudo-terminal pair in raw mode (no echo, no line discipline, 8N1).
#include "pty.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

namespace rbx1::sim {

int open_pty(Pty& pty, std::string& error) {
  int m = posix_openpt(O_RDWR | O_NOCTTY);
  if (m < 0) {
    error = std::string("posix_openpt: ") + std::strerror(errno);
    return -errno;
  }
  if (grantpt(m) != 0 || unlockpt(m) != 0) {
    int e = errno;
    error = std::string("grantpt/unlockpt: ") + std::strerror(e);
    ::close(m);
    return -e;
  }
  const char* name = ptsname(m);
  if (!name) {
    int e = errno;
    error = std::string("ptsname: ") + std::strerror(e);
    ::close(m);
    return -e;
  }
  pty.path = name;
  int s = ::open(name, O_RDWR | O_NOCTTY);
  if (s < 0) {
    int e = errno;
    error = pty.path + ": " + std::strerror(e);
    ::close(m);
    return -e;
  }
  termios t{};
  tcgetattr(s, &t);
  cfmakeraw(&t);
  cfsetispeed(&t, B115200);
  cfsetospeed(&t, B115200);
  tcsetattr(s, TCSANOW, &t);
  fcntl(m, F_SETFL, fcntl(m, F_GETFL) | O_NONBLOCK);
  pty.master = m;
  pty.slave = s;
  return 0;
}

void close_pty(Pty& pty) {
  if (pty.master >= 0) ::close(pty.master);
  if (pty.slave >= 0) ::close(pty.slave);
  pty.master = pty.slave = -1;
}

}  // namespace rbx1::sim
