// main.cpp - rbx1-avrsim: runs the real firmware ELF under simavr behind a pty, paced to real time, driven by a
// control FIFO, and writes step counts, step-ISR cycles and e-stop latency as JSON on exit.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>

extern "C" {
#include "sim_interrupts.h"
}

#include "board.hpp"
#include "clock_file.hpp"
#include "probes.hpp"
#include "trace.hpp"

namespace {

using rbx1::avrsim::Board;
using rbx1::avrsim::Probes;
using rbx1::avrsim::Trace;

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

// The firmware's default ELF sits beside our binary's folder: build/bin/../firmware/rbx1.elf.
std::string default_elf() {
  char buf[4096];
  ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "build/firmware/rbx1.elf";
  std::string self(buf, static_cast<size_t>(n));
  std::string bin_dir = self.substr(0, self.rfind('/'));
  return bin_dir + "/../firmware/rbx1.elf";
}

double now_s() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

// Newline-terminated commands from the control FIFO, read without blocking the simulation.
class ControlFifo {
 public:
  bool open(const std::string& path, std::string& error) {
    struct stat st;
    if (stat(path.c_str(), &st) != 0 && mkfifo(path.c_str(), 0600) != 0) {
      error = path + ": cannot create FIFO: " + std::strerror(errno);
      return false;
    }
    fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK);
    if (fd_ < 0) {
      error = path + ": " + std::strerror(errno);
      return false;
    }
    // Our own writer keeps the FIFO from reporting EOF between clients.
    keep_ = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
    return true;
  }
  bool next(std::string& line) {
    if (fd_ < 0) return false;
    char buf[256];
    ssize_t n;
    while ((n = read(fd_, buf, sizeof buf)) > 0) pending_.append(buf, static_cast<size_t>(n));
    size_t nl = pending_.find('\n');
    if (nl == std::string::npos) return false;
    line = pending_.substr(0, nl);
    pending_.erase(0, nl + 1);
    return true;
  }

 private:
  int fd_ = -1, keep_ = -1;
  std::string pending_;
};

void write_json(const Probes& probes, const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {  // a device or FIFO: write in place, never replace it
    std::ofstream out(path);
    out << probes.to_json().dump() << "\n";
    return;
  }
  std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << probes.to_json().dump() << "\n";
    if (!out) {
      std::fprintf(stderr, "rbx1-avrsim: %s: cannot write\n", tmp.c_str());
      return;
    }
  }
  std::rename(tmp.c_str(), path.c_str());  // readers never see half a file
}

// Drives the e-stop input and tells the probes and the trace about an edge.
struct Estop {
  Board* board;
  Probes* probes;
  Trace* trace;  // null without --trace
  bool pending = false;  // a delayed assertion is scheduled
  long after_step_irq = -1;  // "estop 1 @D[:N]": assert D cycles after the step timer's N-th compare match
  long step_irqs_left = 0;   // (from now; N = 1 when not given)
  void set(bool on) {
    const bool edge = on != board->estop();
    board->set_estop(on);
    if (!edge) return;
    if (on) probes->on_estop_edge(); else probes->on_estop_release();
    if (trace) trace->estop_edge(on);
  }
  // "estop 1 D": assert D cycles from now (random phases against the step interrupt, in the benchmark and tests).
  static void on_step_irq(avr_irq_t*, uint32_t value, void* param) {
    auto* e = static_cast<Estop*>(param);
    if (!value || e->after_step_irq < 0 || --e->step_irqs_left > 0) return;
    avr_cycle_timer_register(e->board->avr(), static_cast<avr_cycle_count_t>(std::max(1L, e->after_step_irq)),
                             &Estop::fire, e);
    e->after_step_irq = -1;
  }
  static avr_cycle_count_t fire(avr_t*, avr_cycle_count_t, void* param) {
    auto* e = static_cast<Estop*>(param);
    e->pending = false;
    e->set(true);
    return 0;
  }
};

// Exit at once, with what the firmware sent written out and the EEPROM saved.
[[noreturn]] void finish(Board& board, const Probes& probes, Trace* trace, const std::string& json_path, int code) {
  std::string err;
  if (trace) trace->flush();
  board.flush();
  if (!board.save_eeprom(err)) std::fprintf(stderr, "rbx1-avrsim: %s\n", err.c_str());
  if (!json_path.empty()) write_json(probes, json_path);
  std::fflush(stdout);
  std::fflush(stderr);
  _exit(code);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rbx1-avrsim: the RBX1 firmware ELF under simavr (atmega2560, 16 MHz), UART0 on a pty"};
  std::string elf = default_elf(), control, json_path, eeprom;
  bool fast = false;
  int isr_vector = -1;
  double max_seconds = 0;
  uint32_t uart_baud = 0;
  std::string trace_path, clock_file, time_function;
  bool hold_for_host = false;
  app.add_option("--elf", elf, "firmware ELF")->capture_default_str();
  app.add_option("--control", control, "control FIFO (estop 0|1 [DELAY_CYCLES|@CYCLES_AFTER_STEP_IRQ[:NTH_IRQ]], limit J 0|1, reset, stats FILE, quit)");
  app.add_option("--json", json_path, "write the measurements here on exit");
  app.add_flag("--fast", fast, "run as fast as possible instead of in real time");
  app.add_option("--eeprom", eeprom, "keep the EEPROM in this file across runs");
  app.add_option("--isr-vector", isr_vector, "the step interrupt's vector number (default: the vector that pulses STEP)");
  app.add_option("--max-seconds", max_seconds, "exit by itself after this many wall-clock seconds (0: never)");
  app.add_option("--uart-baud", uart_baud,
                 "time UART0 bytes at this line rate instead of the firmware's UBRR0 (benchmarks)");
  app.add_option("--trace", trace_path,
                 "log every STEP/DIR edge, interrupt entry/exit and I-bit change with its cycle to this file");
  app.add_option("--time-function", time_function,
                 "with --trace: log every call of the main-loop function at this byte address (hex, avr-nm's): entry "
                 "cycle, cycles to its return, the same less the interrupts inside it");
  app.add_flag("--hold-for-host", hold_for_host,
               "benchmarks: simulated time stands still while the host is late (what the firmware sent waits unread "
               "and nothing the host wrote waits for the firmware) or says it is busy (--clock-file byte 8 = 1), so "
               "figures in simulated cycles count the link, not the host's scheduling");
  app.add_option("--clock-file", clock_file,
                 "a 16-byte file, mapped: the simulated time (cycles, u64 little-endian) at 0, kept current, so a "
                 "host can time out on the board's clock (the harness's --sim-clock, benchmarks); at 8 a byte the "
                 "host sets to 1 while busy (--hold-for-host)");
  CLI11_PARSE(app, argc, argv);

  if (!fast) {
    // Real time needs about a quarter of a core; on a machine busy with builds, ask for a larger share (works as
    // root, harmlessly refused otherwise). Before the pty thread exists, so it inherits the priority.
    if (setpriority(PRIO_PROCESS, 0, -10) != 0) errno = 0;
  }
  Board board;
  std::string error;
  if (!board.open(elf, eeprom, error)) {
    std::fprintf(stderr, "rbx1-avrsim: %s\n", error.c_str());
    return 2;
  }
  ControlFifo fifo;
  if (!control.empty() && !fifo.open(control, error)) {
    std::fprintf(stderr, "rbx1-avrsim: %s\n", error.c_str());
    return 2;
  }
  Probes probes;
  probes.attach(board.avr(), isr_vector);
  Trace trace_log;
  Trace* trace = nullptr;
  if (!trace_path.empty()) {
    if (!trace_log.open(board.avr(), trace_path, error)) {
      std::fprintf(stderr, "rbx1-avrsim: %s\n", error.c_str());
      return 2;
    }
    trace = &trace_log;
  }
  if (!time_function.empty()) {
    char* end = nullptr;
    const unsigned long pc = std::strtoul(time_function.c_str(), &end, 16);
    if (!trace || time_function.empty() || *end || pc == 0 || pc >= 0x40000) {
      std::fprintf(stderr, "rbx1-avrsim: --time-function needs --trace and a flash byte address in hex, got '%s'\n",
                   time_function.c_str());
      return 2;
    }
    trace->time_function(static_cast<uint32_t>(pc));
  }
  Estop estop{&board, &probes, trace};
  // The step timer's compare match raises TIMER1_COMPA (vector 17 on the ATmega2560).
  for (int i = 0; i < board.avr()->interrupts.vector_count; i++)
    if (board.avr()->interrupts.vector[i]->vector == 17)
      avr_irq_register_notify(board.avr()->interrupts.vector[i]->irq + AVR_INT_IRQ_PENDING, &Estop::on_step_irq, &estop);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  volatile uint64_t* sim_clock = nullptr;
  volatile uint8_t* host_busy = nullptr;
  if (!clock_file.empty()) {
    volatile uint8_t* m = rbx1::simpty::map_clock_file(clock_file, error);
    if (!m) {
      std::fprintf(stderr, "rbx1-avrsim: %s\n", error.c_str());
      return 2;
    }
    sim_clock = reinterpret_cast<volatile uint64_t*>(m);
    host_busy = m + 8;
    *sim_clock = board.avr()->cycle;
  }
  std::printf("%s\n", board.pty_path());
  std::fflush(stdout);

  avr_t* avr = board.avr();
  const double hz = avr->frequency;
  // Control and pacing every 250 simulated microseconds: a byte from the host waits at most that long in wall time.
  const avr_cycle_count_t slice = avr->frequency / 4000;
  const double max_lag = 0.200;  // behind real time by more than this (host overloaded): drop the debt
  double t0 = now_s();
  const double started = t0;
  avr_cycle_count_t c0 = avr->cycle;
  std::string line;
  double last_warning = -1e9;

  auto control_commands = [&] {
    while (fifo.next(line)) {
      std::istringstream in(line);
      std::string cmd;
      in >> cmd;
      int a = -1, b = -1;
      std::string arg;
      if (cmd == "estop" && (in >> a) && (a == 0 || a == 1)) {
        long delay = 0;
        std::string at;
        long d = -1, nth = 1;
        if (a == 1 && (in >> at) && at.size() > 1 && at[0] == '@') {
          if (std::sscanf(at.c_str(), "@%ld:%ld", &d, &nth) < 1 || d < 0 || nth < 1) {
            std::fprintf(stderr, "rbx1-avrsim: bad e-stop phase '%s' (@CYCLES[:NTH_IRQ])\n", at.c_str());
            continue;
          }
          estop.after_step_irq = d;
          estop.step_irqs_left = nth;
          estop.pending = true;
        } else if (a == 1 && !at.empty() && (delay = std::atol(at.c_str())) > 0) {
          if (!estop.pending) avr_cycle_timer_register(avr, static_cast<avr_cycle_count_t>(delay), &Estop::fire, &estop);
          estop.pending = true;
        } else {
          if (estop.pending) avr_cycle_timer_cancel(avr, &Estop::fire, &estop);
          estop.pending = false;
          estop.after_step_irq = -1;
          estop.set(a == 1);
        }
      } else if (cmd == "limit" && (in >> a >> b) && a >= 1 && a <= RBX1_JOINTS && (b == 0 || b == 1)) {
        board.set_limit(a - 1, b == 1);
      } else if (cmd == "reset") {
        board.reset();
        probes.on_reset();
      } else if (cmd == "stats" && (in >> arg)) {
        write_json(probes, arg);  // a snapshot while running (benchmarks diff two of them)
        probes.start_window();
      } else if (cmd == "quit") {
        g_stop = 1;
      } else if (!cmd.empty()) {
        std::fprintf(stderr, "rbx1-avrsim: unknown control command '%s'\n", line.c_str());
      }
    }
  };

  while (!g_stop) {
    // The host is late when what the firmware sent waits unread and the firmware has nothing of the host's to
    // read (a host descheduled with its answers waiting), or when it says it is busy (between reading answers and
    // writing what they call for): time stands still until it reads or is done, and pacing resumes from there (no
    // burst to catch up). Control commands still work meanwhile.
    auto late = [&] {
      return hold_for_host &&
             ((host_busy && *host_busy == 1) || (board.host_unread() > 0 && !board.host_pending()));
    };
    if (late()) {
      const double p0 = now_s();
      while (!g_stop && late() && !(max_seconds > 0 && now_s() - started > max_seconds)) {
        control_commands();
        timespec ts{0, 50000};
        nanosleep(&ts, nullptr);
      }
      t0 += now_s() - p0;
    }
    const avr_cycle_count_t until = avr->cycle + slice;
    while (avr->cycle < until) {
      int state = avr_run(avr);
      if (trace) trace->after_instruction();
      if (state == cpu_Done || state == cpu_Crashed) {
        std::fprintf(stderr, "rbx1-avrsim: the firmware %s at pc 0x%x, cycle %llu\n",
                     state == cpu_Crashed ? "crashed" : "stopped", avr->pc,
                     static_cast<unsigned long long>(avr->cycle));
        finish(board, probes, trace, json_path, 1);
      }
    }
    board.set_uart_timing(uart_baud);
    if (sim_clock) *sim_clock = avr->cycle;  // before the pump: a host never sees an answer before its time
    board.pump();
    control_commands();
    const double now = now_s();
    if (max_seconds > 0 && now - started > max_seconds) {
      std::fprintf(stderr, "rbx1-avrsim: --max-seconds reached\n");
      break;
    }
    if (fast) continue;
    const double ahead = (avr->cycle - c0) / hz - (now - t0);
    if (ahead > 0) {
      timespec ts{0, static_cast<long>(std::min(ahead, 0.5) * 1e9)};
      nanosleep(&ts, nullptr);
    } else if (-ahead > max_lag) {
      t0 = now - max_lag;  // forgive the debt: a burst would make firmware timeouts fire early
      c0 = avr->cycle;
      if (now - last_warning > 5.0) {  // say so: timing checks against this board are then unreliable
        std::fprintf(stderr, "rbx1-avrsim: simulation behind real time by over %.0f ms (host CPU overloaded)\n",
                     max_lag * 1000);
        last_warning = now;
      }
    }
  }
  finish(board, probes, trace, json_path, 0);
}
