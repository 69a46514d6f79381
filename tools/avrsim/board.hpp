// board.hpp - the simulated Arduino Mega 2560: firmware ELF on an atmega2560 at 16 MHz, UART0 on a pty,
// EEPROM optionally kept in a file, limit switch and e-stop inputs driven from outside.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "pinmap.hpp"
#include "pty_bridge.hpp"

extern "C" {
#include "avr_uart.h"
#include "sim_avr.h"
}

namespace rbx1::avrsim {

class Board {
 public:
  // Loads the ELF and bridges UART0 to a pty through pump(), in the simulation's thread (tools/simpty). Returns
  // false with error set.
  bool open(const std::string& elf, const std::string& eeprom_file, std::string& error);
  avr_t* avr() const { return avr_; }
  const char* pty_path() const { return pty_name_.c_str(); }
  // Drives an input pin to its asserted or released level.
  void set_estop(bool asserted);
  bool estop() const { return estop_; }
  void set_limit(int joint, bool triggered);  // joint 0..5
  // Power cycle: EEPROM kept (and saved), everything else back to reset state, inputs re-driven.
  void reset();
  // simavr 1.6 times a UART byte as 11 bits (it always counts a parity bit); 8N1 is 10. Sets UART0's byte time
  // from the firmware's UBRR0/U2X0, or from forced_baud when non-zero (a line rate other than the firmware's).
  void set_uart_timing(uint32_t forced_baud);
  // Bytes the firmware sent that wait unread on the pty (the host has not read them yet).
  int host_unread() const;
  // Whether bytes the host wrote still wait for the firmware's UART (in the pty or the bridge's buffer).
  bool host_pending() const;
  // Moves bytes between the pty and UART0; the run loop calls it between slices (simpty::PtyBridge).
  void pump();
  // Writes out what the firmware sent and the host has not got yet (at exit).
  void flush();
  // Writes the EEPROM to the --eeprom file (atomic rename). No-op without one.
  bool save_eeprom(std::string& error);

 private:
  void drive(PortPin p, uint8_t level, bool force);
  void drive_inputs(bool force);
  struct Pull {
    uint8_t mask = 0, value = 0;
  };
  std::array<Pull, 16> pulls_{};  // per port letter - 'A'

  avr_t* avr_ = nullptr;
  ::avr_uart_t* uart0_ = nullptr;
  std::unique_ptr<simpty::PtyBridge> bridge_;
  std::string pty_name_;
  std::string eeprom_file_;
  bool estop_ = false;
  std::array<bool, RBX1_JOINTS> limits_{};
};

}  // namespace rbx1::avrsim
