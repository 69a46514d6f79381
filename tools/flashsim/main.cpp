// main.cpp - rbx1-avrboard: an Arduino Mega 2560 as it leaves the factory, under simavr: Debian's stk500v2
// bootloader in the boot section, flash and EEPROM kept in files, UART0 on a pty with the auto-reset modelled.
#include <sys/resource.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdarg>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

extern "C" {
#include "avr_eeprom.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_io.h"
}

#include "autoreset.hpp"
#include "flash_image.hpp"
#include "clock_file.hpp"
#include "pty_bridge.hpp"

namespace {

using rbx1::flashsim::AutoReset;
using rbx1::flashsim::kBootStart;

constexpr uint32_t kFrequency = 16000000;
constexpr size_t kEepromSize = 4096;
constexpr uint16_t kMcusr = 0x54;  // MCUSR's data address (I/O 0x34)
constexpr uint8_t kExtrf = 1 << 1;

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

void log_to_stderr(avr_t* avr, const int level, const char* format, va_list ap) {
  if (level <= (avr ? avr->log : static_cast<int>(LOG_WARNING))) std::vfprintf(stderr, format, ap);
}
void no_sleep(avr_t*, avr_cycle_count_t) {}  // pacing is the run loop's job

double now_s() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

bool load_eeprom(avr_t* avr, const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.resize(std::min(bytes.size(), kEepromSize));
  if (bytes.empty()) return false;
  avr_eeprom_desc_t d{bytes.data(), 0, static_cast<uint32_t>(bytes.size())};
  avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &d);
  return true;
}

// Atomic (temp file, rename): a run killed mid-write leaves the previous EEPROM.
bool save_eeprom(avr_t* avr, const std::string& file) {
  if (file.empty()) return true;
  avr_eeprom_desc_t d{nullptr, 0, static_cast<uint32_t>(kEepromSize)};
  avr_ioctl(avr, AVR_IOCTL_EEPROM_GET, &d);  // simavr 1.6 answers -1 even on success: check the copy
  if (!d.ee) return false;
  const std::string tmp = file + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(d.ee), static_cast<std::streamsize>(kEepromSize));
    if (!out) return false;
  }
  return std::rename(tmp.c_str(), file.c_str()) == 0;
}

// simavr 1.6 times a UART byte as 11 bits; 8N1 is 10: from UBRR0 and U2X0 as the running program set them.
void set_uart_timing(avr_t* avr, avr_uart_t* uart0) {
  const uint32_t ubrr = avr->data[0xC4] | ((avr->data[0xC5] & 0x0F) << 8);  // UBRR0L, UBRR0H
  const bool u2x = avr->data[0xC0] & 0x02;                                     // UCSR0A.U2X0
  uart0->cycles_per_byte = (ubrr + 1) * (u2x ? 8 : 16) * 10;
}

// The RESET pin: everything but flash and EEPROM back to its reset state, MCUSR says an external reset.
void reset_board(avr_t* avr) {
  avr_reset(avr);
  avr->data[kMcusr] = kExtrf;
}

// The default bootloader is Debian's arduino-core-avr copy; the Arduino IDE burns the same file.
const char* kDebianBootloader =
    "/usr/share/arduino/hardware/arduino/avr/bootloaders/stk500v2/stk500boot_v2_mega2560.hex";

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rbx1-avrboard: an Arduino Mega 2560 with its stk500v2 bootloader under simavr, UART0 on a pty"};
  std::string flash_file, eeprom_file, bootloader = kDebianBootloader, clock_file;
  double max_seconds = 0;
  app.add_option("--flash", flash_file, "the board's flash, kept in this file (created blank when missing)")
      ->required();
  app.add_option("--eeprom", eeprom_file, "the board's EEPROM, kept in this file across runs");
  app.add_option("--bootloader", bootloader, "bootloader HEX for the boot section")->capture_default_str();
  app.add_option("--max-seconds", max_seconds, "exit by itself after this many wall-clock seconds (0: never)");
  app.add_option("--clock-file", clock_file,
                 "a 16-byte file, mapped: the simulated time since start (cycles, u64 little-endian) at 0, kept "
                 "current, so a host can time out on the board's clock (as rbx1-avrsim's; bytes 8-15 unused)");
  CLI11_PARSE(app, argc, argv);

  if (setpriority(PRIO_PROCESS, 0, -10) != 0) errno = 0;  // real time on a busy machine (root only)
  avr_global_logger_set(log_to_stderr);
  avr_t* avr = avr_make_mcu_by_name("atmega2560");
  if (!avr) {
    std::fprintf(stderr, "rbx1-avrboard: simavr has no atmega2560 core\n");
    return 2;
  }
  avr_init(avr);
  avr->frequency = kFrequency;
  avr->sleep = no_sleep;
  std::string error;
  if (!rbx1::flashsim::map_flash(avr, flash_file, bootloader, error)) {
    std::fprintf(stderr, "rbx1-avrboard: %s\n", error.c_str());
    return 2;
  }
  if (!eeprom_file.empty()) load_eeprom(avr, eeprom_file);

  // UART0 on a pty, bridged in this thread (tools/simpty: simavr's uart_pty thread lost avrdude's exchanges under
  // load). Our own open of the slave is kept for the run: the auto-reset model reads the port's termios through it.
  rbx1::simpty::PtyBridge bridge;
  AutoReset autoreset;
  if (!bridge.open(avr, '0', error) || !autoreset.open(bridge.path().c_str(), bridge.slave_fd(), error)) {
    std::fprintf(stderr, "rbx1-avrboard: %s\n", error.c_str());
    return 2;
  }
  avr_uart_t* uart0 = bridge.uart();
  termios tio{};
  tcgetattr(bridge.slave_fd(), &tio);
  tio.c_cflag |= HUPCL;  // as a new serial tty has it (a new pty has it clear)
  tcsetattr(bridge.slave_fd(), TCSANOW, &tio);

  // The board's clock for hosts that pace themselves on it (the harness's --clock-file): written before the pty
  // path, so it exists once a host can talk. Monotonic across resets (avr->cycle is not).
  volatile uint64_t* sim_clock = nullptr;
  uint64_t sim_cycles = 0;
  if (!clock_file.empty()) {
    std::string error;
    volatile uint8_t* m = rbx1::simpty::map_clock_file(clock_file, error);
    if (!m) {
      std::fprintf(stderr, "rbx1-avrboard: %s\n", error.c_str());
      return 2;
    }
    sim_clock = reinterpret_cast<volatile uint64_t*>(m);
    *sim_clock = 0;
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  std::printf("%s\n", bridge.path().c_str());
  std::fflush(stdout);

  reset_board(avr);  // power on into the boot section (BOOTRST)
  bridge.pump();
  const double started = now_s();
  double t0 = started, sim_s = 0;  // simulated seconds since start (avr->cycle restarts at every reset)
  const avr_cycle_count_t slice = kFrequency / 4000;  // 250 simulated us between looks at the outside world
  bool in_boot = true, hung = false;
  double last_warning = -1e9;
  while (!g_stop) {
    const avr_cycle_count_t start = avr->cycle, until = start + slice;
    while (!hung && avr->cycle < until) {
      const int state = avr_run(avr);
      if (state == cpu_Done || state == cpu_Crashed) {
        // simavr stops the core (e.g. an opcode it cannot decode, as a corrupted upload gives); the board hangs
        // with its port open until a reset, as a chip running garbage would look from the host.
        std::fprintf(stderr, "rbx1-avrboard: %.3f s: the program %s at pc 0x%x: the board hangs until a reset\n",
                     sim_s, state == cpu_Crashed ? "crashed" : "stopped", avr->pc);
        hung = true;
      }
      if (avr->cycle < start) break;  // the watchdog reset the core
    }
    const avr_cycle_count_t ran = hung ? slice : avr->cycle >= start ? avr->cycle - start : avr->cycle;
    sim_cycles += ran;
    sim_s = static_cast<double>(sim_cycles) / kFrequency;
    if (sim_clock) *sim_clock = sim_cycles;
    set_uart_timing(avr, uart0);
    bridge.pump();
    const bool boot_now = avr->pc >= kBootStart;
    if (in_boot && !boot_now)
      std::fprintf(stderr, "rbx1-avrboard: %.3f s: bootloader left, application running\n", sim_s);
    else if (!in_boot && boot_now)
      std::fprintf(stderr, "rbx1-avrboard: %.3f s: in the bootloader\n", sim_s);
    in_boot = boot_now;
    if (autoreset.take_reset()) {
      save_eeprom(avr, eeprom_file);
      reset_board(avr);
      bridge.pump();
      in_boot = true;
      hung = false;
      std::fprintf(stderr, "rbx1-avrboard: %.3f s: reset, in the bootloader\n", sim_s);
    }
    const double now = now_s();
    if (max_seconds > 0 && now - started > max_seconds) {
      std::fprintf(stderr, "rbx1-avrboard: --max-seconds reached\n");
      break;
    }
    const double ahead = sim_s - (now - t0);
    if (ahead > 0) {
      timespec ts{0, static_cast<long>(std::min(ahead, 0.5) * 1e9)};
      nanosleep(&ts, nullptr);
    } else if (-ahead > 0.2) {
      t0 = now - sim_s;  // forgive the debt rather than race (a burst would fire timeouts early)
      if (now - last_warning > 5.0) {
        std::fprintf(stderr, "rbx1-avrboard: simulation behind real time by over 200 ms (host CPU overloaded)\n");
        last_warning = now;
      }
    }
  }
  // Keep the files, write out what the board sent, then leave.
  bridge.flush();
  if (!save_eeprom(avr, eeprom_file)) std::fprintf(stderr, "rbx1-avrboard: %s: cannot save the EEPROM\n", eeprom_file.c_str());
  rbx1::flashsim::sync_flash(avr);
  std::fprintf(stderr, "rbx1-avrboard: %.3f s simulated in %.3f s\n", sim_s, now_s() - started);
  std::fflush(stdout);
  std::fflush(stderr);
  _exit(0);
}
