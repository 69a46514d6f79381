// pty_bridge.hpp - a simulated AVR's UART on a pty, bridged in the simulation's own thread (rbx1-avrsim
// --hold-for-host, rbx1-avrboard).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

extern "C" {
#include "avr_uart.h"
#include "sim_avr.h"
}

namespace rbx1::simpty {

// UART `uart` ('0'..'3') of avr readied for a pty: no usleep() whenever the program polls UCSRnA with nothing to do
// (pacing is the run loop's job), no copy of its output on our stdout (where the first line is the pty path).
// Returns the UART, nullptr when the chip has none by that name.
avr_uart_t* prepare_uart(avr_t* avr, char uart);
// Opens a pty's slave, raw (a cooked slave echoes the program's bytes back into its UART): the descriptor, or -1
// with error set.
int open_raw_slave(const std::string& path, std::string& error);

// simavr's uart_pty (libsimavrparts) moves the bytes in a thread of its own: on a loaded machine that thread kept
// the firmware's answers while simulated time ran on, its FIFOs are shared without locks, and its writes are
// unchecked. Here the bytes move in the thread that runs the AVR: a cycle timer polls the pty's master every 1024
// cycles (64 us at 16 MHz), so a byte the host writes reaches the UART that late at most (later only while the
// UART says XOFF: its input FIFO full, or its receiver off after a reset); what the program sends is written a
// burst at a time, once the line has been quiet for two byte times (a host woken for every byte would spend its
// time in wake-ups), or at 64 bytes.
class PtyBridge {
 public:
  // Makes the pty, opens its slave (raw: a cooked slave echoes the program's bytes back into its UART) and keeps
  // it open, and hooks UART `uart` ('0'..'3'). Returns false with error set.
  bool open(avr_t* avr, char uart, std::string& error);
  const std::string& path() const { return path_; }
  // Our own open of the slave, raw, held for the run (the pty never reports EIO while no host has it open).
  int slave_fd() const { return slave_fd_; }
  avr_uart_t* uart() const { return uart_; }
  // Moves bytes both ways; the run loop calls it between slices and after a reset of its own. A reset (the RESET
  // pin, the watchdog) clears simavr's cycle timers: the pump is armed again here, and the bridge starts over as
  // the reset UART does: its receiver off (XOFF) until the program enables it, the host's bytes the program had not
  // taken dropped, the program's bytes already sent written out.
  void pump();
  // Bytes the program sent that wait unread on the pty (the host has not read them yet).
  int host_unread() const;
  // Whether bytes the host wrote still wait for the UART (in the pty or the bridge's buffer).
  bool host_pending() const;
  // Writes out everything the program sent (at exit): what the pty has no room for is dropped.
  void flush();

 private:
  static void on_output(avr_irq_t* irq, uint32_t value, void* param);
  static void on_xon(avr_irq_t* irq, uint32_t value, void* param);
  static void on_xoff(avr_irq_t* irq, uint32_t value, void* param);
  static avr_cycle_count_t on_timer(avr_t* avr, avr_cycle_count_t when, void* param);
  void feed();
  void take_input();
  void write_out();
  void pump_output();

  avr_t* avr_ = nullptr;
  avr_uart_t* uart_ = nullptr;
  avr_irq_t* uart_in_ = nullptr;
  int master_fd_ = -1;  // non-blocking
  int slave_fd_ = -1;
  std::string path_;
  bool xon_ = false;               // the UART takes input (receiver on, input FIFO not full)
  std::vector<uint8_t> in_, out_;  // host -> UART not yet taken, UART -> host not yet written
  size_t in_done_ = 0;
  avr_cycle_count_t last_out_ = 0;  // when the program last sent a byte
};

}  // namespace rbx1::simpty
