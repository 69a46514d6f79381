// serial_port.cpp - termios2 raw-mode setup; <asm/termbits.h> replaces <termios.h> here (they cannot mix).
#include "serial_port.hpp"

#include <asm/termbits.h>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <unistd.h>

namespace rbx1::link {

bool supported_baud(int baud) { return baud == 115200 || baud == 230400 || baud == 250000; }

namespace {
// The classic termios rate of a baud, 0 when it has none (250000: termios2 only).
speed_t classic_rate(int baud) { return baud == 115200 ? B115200 : baud == 230400 ? B230400 : 0; }

// Where the termios2 ioctls are missing (ENOSYS: qemu-user 7.2, which tools/cross/test-arm64 runs rbx1d under;
// every Linux kernel has them): the same raw mode with the classic ioctls, for the rates they can name.
int configure_classic(int fd, int baud) {
  speed_t rate = classic_rate(baud);
  struct termios t;
  if (rate == 0) return -ENOSYS;
  if (ioctl(fd, TCGETS, &t) < 0) return -errno;
  t.c_iflag &= ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF | IXANY);
  t.c_oflag &= ~OPOST;
  t.c_lflag &= ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
  t.c_cflag &= ~(CSIZE | PARENB | CSTOPB | CRTSCTS | HUPCL | CBAUD);
  t.c_cflag |= CS8 | CREAD | CLOCAL | rate;
  t.c_cc[VMIN] = 1;
  t.c_cc[VTIME] = 0;
  if (ioctl(fd, TCSETS, &t) < 0) return -errno;
  ioctl(fd, TCFLSH, TCIOFLUSH);
  return 0;
}
}  // namespace

int configure_serial(int fd, int baud) {
  if (!supported_baud(baud)) return -EINVAL;
  struct termios2 t;
  if (ioctl(fd, TCGETS2, &t) < 0) return errno == ENOSYS ? configure_classic(fd, baud) : -errno;
  // cfmakeraw() by hand: no input/output processing, no echo, no signals, 8 data bits, no parity.
  t.c_iflag &= ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF | IXANY);
  t.c_oflag &= ~OPOST;
  t.c_lflag &= ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
  t.c_cflag &= ~(CSIZE | PARENB | CSTOPB | CRTSCTS | HUPCL | CBAUD | (CBAUD << IBSHIFT));
  t.c_cflag |= CS8 | CREAD | CLOCAL | BOTHER | (BOTHER << IBSHIFT);
  t.c_ispeed = t.c_ospeed = static_cast<speed_t>(baud);
  t.c_cc[VMIN] = 1;  // reads are driven by poll(); a read after POLLIN never blocks
  t.c_cc[VTIME] = 0;
  if (ioctl(fd, TCSETS2, &t) < 0) return -errno;
  ioctl(fd, TCFLSH, TCIOFLUSH);  // drop whatever the board printed before we were listening
  return 0;
}

int serial_baud(int fd) {
  struct termios2 t;
  if (ioctl(fd, TCGETS2, &t) < 0) {
    if (errno != ENOSYS) return -errno;
    struct termios c;  // the classic ioctls (configure_classic)
    if (ioctl(fd, TCGETS, &c) < 0) return -errno;
    speed_t rate = c.c_cflag & CBAUD;
    return rate == B115200 ? 115200 : rate == B230400 ? 230400 : -ENOSYS;
  }
  return static_cast<int>(t.c_ospeed);
}

int open_serial(const std::string& path, int baud, std::string& error) {
  if (!supported_baud(baud)) {
    error = path + ": unsupported baud " + std::to_string(baud) + " (115200, 230400 or 250000)";
    return -EINVAL;
  }
  // O_NONBLOCK so the open does not wait for carrier; cleared below for blocking writes.
  int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    int e = errno;
    error = path + ": " + std::strerror(e);
    return -e;
  }
  // TIOCEXCL stops other opens, except root's; the advisory lock (as pyserial's exclusive=True takes) holds for
  // root too, so two links never share a port.
  if (flock(fd, LOCK_EX | LOCK_NB) < 0) {
    int e = errno == EWOULDBLOCK ? EBUSY : errno;
    error = path + ": in use by another program";
    ::close(fd);
    return -e;
  }
  if (ioctl(fd, TIOCEXCL) < 0) {
    int e = errno;
    error = path + ": not a serial device (" + std::strerror(e) + ")";
    ::close(fd);
    return -e;
  }
  int r = configure_serial(fd, baud);
  if (r < 0) {
    error = path + ": cannot set raw mode at " + std::to_string(baud) + " baud (" + std::strerror(-r) + ")";
    ::close(fd);
    return r;
  }
  int flags = fcntl(fd, F_GETFL);
  if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) < 0) {
    int e = errno;
    error = path + ": " + std::strerror(e);
    ::close(fd);
    return -e;
  }
  return fd;
}

}  // namespace rbx1::link
