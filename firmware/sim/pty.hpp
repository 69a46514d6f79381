// pty.hpp - a raw pseudo-terminal for the simulated firmware's serial port.
#pragma once

#include <string>

namespace rbx1::sim {

struct Pty {
  int master = -1;  // the firmware's side (non-blocking)
  int slave = -1;   // kept open so the port survives clients opening and closing it
  std::string path;
};

// Opens a pty in raw mode. Returns 0 or a negative errno; error names the failing step.
int open_pty(Pty& pty, std::string& error);
void close_pty(Pty& pty);

}  // namespace rbx1::sim
