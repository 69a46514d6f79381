// serial_port.hpp - opens a serial device in raw mode at a given baud, without hang-up on close, exclusively.
#pragma once
#include <string>

namespace rbx1::link {

// The bauds the firmware speaks; anything else is refused so a typo cannot pass as a working link.
bool supported_baud(int baud);

// Opens path (a tty, a pty slave or a symlink to one) for reading and writing: raw 8N1, no flow control,
// HUPCL cleared (opening/closing must not reset an Arduino), TIOCEXCL plus an flock (-EBUSY when another
// program has it), blocking writes.
// Returns the fd, or a negative errno with error set to "PATH: reason".
int open_serial(const std::string& path, int baud, std::string& error);

// Sets raw 8N1 at baud on an open tty fd (termios2 with BOTHER, so 250000 works on Linux). 0 or -errno.
int configure_serial(int fd, int baud);

// The output speed the kernel reports for fd (termios2), or a negative errno.
int serial_baud(int fd);

}  // namespace rbx1::link
