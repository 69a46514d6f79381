// autoreset.hpp - the Mega's auto-reset on a pty: DTR modelled from the port's opens, closes and HUPCL.
#pragma once

#include <atomic>
#include <string>
#include <thread>

namespace rbx1::flashsim {

// On the board, DTR from the USB serial chip reaches RESET through a 100 nF capacitor: asserting DTR (what every
// open() of the tty does) pulses RESET, and DTR stays asserted until the last close, where the kernel drops it
// only when HUPCL is set. A pty has no modem lines (TIOCMGET/TIOCMSET fail with ENOTTY), so DTR is derived:
// - the pty's slave is watched with inotify; an open while no client has it open asserts DTR;
// - at the last client's close, DTR drops if the port's termios (shared by every open of the pty, read from our
//   own descriptor) has HUPCL set, and stays asserted if a client cleared it (rbx1d does);
// - asserting DTR while it was dropped is the reset. DTR starts dropped (a board just plugged in).
// A thread blocks on the inotify descriptor so the termios is read right at the close, before the next program
// (avrdude after tools/flash's stty) can open the port and change it.
class AutoReset {
 public:
  // slave_fd: our own open of slave_path, made before this call (it is not counted as a client).
  bool open(const char* slave_path, int slave_fd, std::string& error);
  // True when DTR was asserted since the last call (reset the board).
  bool take_reset() { return resets_.exchange(0) > 0; }

 private:
  void watch();
  int inotify_ = -1, slave_fd_ = -1;
  int clients_ = 0;
  bool dtr_ = false;
  std::atomic<int> resets_{0};
  std::thread thread_;
};

}  // namespace rbx1::flashsim
