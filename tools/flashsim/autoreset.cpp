// autoreset.cpp - DTR from the pty's opens and closes (inotify) and HUPCL at the last close (termios).
#include "autoreset.hpp"

#include <sys/inotify.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace rbx1::flashsim {

bool AutoReset::open(const char* slave_path, int slave_fd, std::string& error) {
  slave_fd_ = slave_fd;
  inotify_ = inotify_init1(IN_CLOEXEC);
  if (inotify_ < 0 || inotify_add_watch(inotify_, slave_path, IN_OPEN | IN_CLOSE) < 0) {
    error = std::string(slave_path) + ": inotify: " + std::strerror(errno);
    return false;
  }
  thread_ = std::thread(&AutoReset::watch, this);
  thread_.detach();  // blocks in read() until the process exits
  return true;
}

void AutoReset::watch() {
  alignas(inotify_event) char buf[4096];
  ssize_t n;
  while ((n = read(inotify_, buf, sizeof buf)) > 0 || errno == EINTR) {
    for (char* p = buf; p < buf + n;) {
      const auto* ev = reinterpret_cast<const inotify_event*>(p);
      p += sizeof(inotify_event) + ev->len;
      if (ev->mask & IN_OPEN) {
        if (clients_++ == 0 && !dtr_) {
          dtr_ = true;
          resets_++;
          std::fprintf(stderr, "rbx1-avrboard: port opened, DTR asserted: reset\n");
        }
      } else if (ev->mask & (IN_CLOSE_WRITE | IN_CLOSE_NOWRITE)) {
        if (clients_ > 0 && --clients_ == 0) {
          termios t{};
          const bool hupcl = tcgetattr(slave_fd_, &t) != 0 || (t.c_cflag & HUPCL);
          if (hupcl) dtr_ = false;
          std::fprintf(stderr, "rbx1-avrboard: port closed, HUPCL %s: DTR %s\n", hupcl ? "set" : "clear",
                       hupcl ? "dropped (the next open resets the board)" : "kept asserted (no reset at the next open)");
        }
      }
    }
  }
}

}  // namespace rbx1::flashsim
