// main.cpp - rbx1-simfw: the firmware core on the simulated board, in real time, behind a pty (path on the first
// stdout line), with a control FIFO, a move log and link fault injection (see firmware/README.md).
#include <CLI/CLI.hpp>

#include <poll.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <sstream>
#include <map>
#include <string>
#include <vector>

#include "firmware.h"
#include "rbx1_proto.h"
#include "hal_sim.hpp"
#include "link_faults.hpp"
#include "pty.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

// EEPROM file: 4096 bytes; missing or short means blank (0xFF) for the rest.
void load_eeprom(const std::string& path) {
  rbx1::sim::erase_eeprom();
  std::ifstream f(path, std::ios::binary);
  if (!f) return;
  auto& e = rbx1::sim::board().eeprom;
  f.read(reinterpret_cast<char*>(e.data()), (std::streamsize)e.size());
}

bool save_eeprom(const std::string& path) {
  std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    auto& e = rbx1::sim::board().eeprom;
    f.write(reinterpret_cast<const char*>(e.data()), (std::streamsize)e.size());
    if (!f) return false;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0;
}

std::string json_array(const int32_t* v) {
  std::string s = "[";
  for (int i = 0; i < RBX1_JOINTS; i++) s += (i ? "," : "") + std::to_string(v[i]);
  return s + "]";
}

// `drop TYPE N`: the next N responses to requests of TYPE (an id) are lost on the line after the firmware
// executed the request (an answer that never arrives: the host retransmits, gets the remembered one, loses it too).
std::map<uint8_t, int> g_drop;

// Removes the dropped responses from the firmware's output. The firmware writes whole frames, one after another.
void drop_responses(std::vector<uint8_t>& tx) {
  if (g_drop.empty()) return;
  std::vector<uint8_t> kept;
  size_t i = 0;
  while (i + 4 <= tx.size() && tx[i] == RBX1_SYNC) {
    size_t len = size_t(tx[i + 1]) + RBX1_FRAME_OVERHEAD;
    if (i + len > tx.size()) break;
    auto it = g_drop.find(uint8_t(tx[i + 3] & 0x7F));
    if ((tx[i + 3] & 0x80) && it != g_drop.end() && it->second > 0) {
      if (--it->second == 0) g_drop.erase(it);
    } else {
      kept.insert(kept.end(), tx.begin() + long(i), tx.begin() + long(i + len));
    }
    i += len;
  }
  kept.insert(kept.end(), tx.begin() + long(i), tx.end());
  tx.swap(kept);
}

// Control FIFO commands: estop 0|1, limit J 0|1, drop TYPE N, reset, quit. Returns false on quit.
bool control_command(const std::string& line, std::string& error) {
  std::istringstream in(line);
  std::string cmd;
  in >> cmd;
  auto& b = rbx1::sim::board();
  if (cmd.empty()) return true;
  if (cmd == "quit") return false;
  if (cmd == "estop") {
    int v = -1;
    in >> v;
    if (v != 0 && v != 1) error = "usage: estop 0|1";
    else b.estop = v == 1;
  } else if (cmd == "limit") {
    int j = 0, v = -1;
    in >> j >> v;
    if (j < 1 || j > RBX1_JOINTS || (v != 0 && v != 1)) {
      error = "usage: limit J 0|1 (J = 1.." + std::to_string(RBX1_JOINTS) + ")";
    } else if (v) {
      b.limits = (uint8_t)(b.limits | (1u << (j - 1)));
    } else {
      b.limits = (uint8_t)(b.limits & ~(1u << (j - 1)));
    }
  } else if (cmd == "drop") {
    int type = -1, count = -1;
    in >> type >> count;
    if (type < 1 || type > 0x7E || count < 0) error = "usage: drop TYPE N (TYPE = request id 1..126)";
    else g_drop[uint8_t(type)] = count;
  } else if (cmd == "reset") {
    rbx1::sim::power_on();
    fw_setup();
  } else {
    error = "unknown control command: " + cmd;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rbx1-simfw: the RBX1 firmware core on a simulated board, behind a pty"};
  std::string eeprom_path, control_path, log_path, link_path;
  rbx1::sim::FaultRates rates;
  uint64_t seed = 1;
  double time_scale = 1.0;
  app.add_option("--eeprom", eeprom_path, "keep the EEPROM in this file across runs");
  app.add_option("--control", control_path, "control FIFO (created if missing): estop 0|1, limit J 0|1, reset, quit");
  app.add_option("--log-moves", log_path, "write one JSON line per completed queue entry");
  app.add_option("--link", link_path,
                 "also make this path a symlink to the pty (replaced atomically; removed at exit): a board that "
                 "comes back on the same device name after a power cycle");
  app.add_option("--corrupt", rates.corrupt, "per-byte probability of corrupting a byte")->check(CLI::Range(0.0, 1.0));
  app.add_option("--drop", rates.drop, "per-byte probability of dropping a byte")->check(CLI::Range(0.0, 1.0));
  app.add_option("--duplicate", rates.duplicate, "per-byte probability of duplicating a byte")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--delay-ms", rates.delay_ms, "delay of a delayed byte")->check(CLI::Range(0.0, 60000.0));
  app.add_option("--delay-rate", rates.delay_rate, "per-byte probability of delaying a byte")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--seed", seed, "random seed of the fault injection");
  app.add_option("--time-scale", time_scale,
                 "simulated seconds per wall-clock second (the board runs this much faster; host timeouts such as "
                 "the heartbeat are in simulated time)")
      ->check(CLI::Range(0.1, 50.0));
  CLI11_PARSE(app, argc, argv);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  if (!eeprom_path.empty()) load_eeprom(eeprom_path);
  else rbx1::sim::erase_eeprom();

  int control_fd = -1, control_keep = -1;
  if (!control_path.empty()) {
    struct stat st {};
    if (stat(control_path.c_str(), &st) != 0) {
      if (mkfifo(control_path.c_str(), 0600) != 0) {
        std::cerr << "rbx1-simfw: " << control_path << ": " << std::strerror(errno) << "\n";
        return 1;
      }
    } else if (!S_ISFIFO(st.st_mode)) {
      std::cerr << "rbx1-simfw: " << control_path << ": exists and is not a FIFO\n";
      return 1;
    }
    control_fd = open(control_path.c_str(), O_RDONLY | O_NONBLOCK);
    control_keep = open(control_path.c_str(), O_WRONLY | O_NONBLOCK);  // no EOF when writers come and go
    if (control_fd < 0) {
      std::cerr << "rbx1-simfw: " << control_path << ": " << std::strerror(errno) << "\n";
      return 1;
    }
  }

  FILE* log = nullptr;
  if (!log_path.empty()) {
    log = std::fopen(log_path.c_str(), "w");
    if (!log) {
      std::cerr << "rbx1-simfw: " << log_path << ": " << std::strerror(errno) << "\n";
      return 1;
    }
    rbx1::sim::board().on_entry_done = [log](uint8_t kind, uint16_t n, const int32_t* target, const int32_t* start,
                                             const int32_t* end, uint16_t duration_ms, uint16_t pulse_us) {
      timespec now{};
      clock_gettime(CLOCK_MONOTONIC, &now);
      std::fprintf(log, "{\"n\":%u,\"kind\":\"%s\",\"target\":%s,\"start\":%s,\"end\":%s,\"duration_ms\":%u,"
                   "\"pulse_us\":%u,\"mono_ns\":%lld}\n",
                   n, kind ? "gripper" : "move", json_array(kind ? end : target).c_str(), json_array(start).c_str(),
                   json_array(end).c_str(), duration_ms, pulse_us,
                   (long long)now.tv_sec * 1000000000LL + now.tv_nsec);
      std::fflush(log);
    };
  }

  rbx1::sim::Pty pty;
  std::string error;
  if (rbx1::sim::open_pty(pty, error) != 0) {
    std::cerr << "rbx1-simfw: " << error << "\n";
    return 1;
  }
  if (!link_path.empty()) {
    std::string tmp = link_path + ".new";
    ::unlink(tmp.c_str());
    if (::symlink(pty.path.c_str(), tmp.c_str()) != 0 || std::rename(tmp.c_str(), link_path.c_str()) != 0) {
      std::cerr << "rbx1-simfw: " << link_path << ": " << std::strerror(errno) << "\n";
      return 1;
    }
  }
  std::printf("%s\n", pty.path.c_str());
  std::fflush(stdout);

  rbx1::sim::LinkFaults to_fw(rates, seed), from_fw(rates, seed * 7919 + 1);
  rbx1::sim::power_on();
  fw_setup();
  auto t0 = std::chrono::steady_clock::now();
  auto& board = rbx1::sim::board();
  std::string out_pending, control_buf;
  bool running = true;
  while (running && !g_stop) {
    auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
    // Catch up every interrupt due by now: step counts stay exact whatever the host's scheduling.
    rbx1::sim::run_until((uint64_t)((double)ns * time_scale) / 500);
    double now_ms = (double)ns / 1e6;

    uint8_t buf[256];
    ssize_t n;
    while ((n = read(pty.master, buf, sizeof(buf))) > 0)
      for (ssize_t i = 0; i < n; i++) to_fw.push(buf[i], now_ms);
    to_fw.deliver(now_ms, [&](uint8_t b) { board.rx.push_back(b); });

    fw_loop();

    drop_responses(board.tx);
    for (uint8_t b : board.tx) from_fw.push(b, now_ms);
    board.tx.clear();
    from_fw.deliver(now_ms, [&](uint8_t b) { out_pending.push_back((char)b); });
    if (!out_pending.empty()) {
      ssize_t w = write(pty.master, out_pending.data(), out_pending.size());
      if (w > 0) out_pending.erase(0, (size_t)w);
      if (out_pending.size() > 65536) out_pending.clear();  // nobody reads the port: the line drops it
    }

    if (control_fd >= 0) {
      char cb[256];
      while ((n = read(control_fd, cb, sizeof(cb))) > 0) control_buf.append(cb, (size_t)n);
      size_t pos;
      while (running && (pos = control_buf.find('\n')) != std::string::npos) {
        std::string line = control_buf.substr(0, pos);
        control_buf.erase(0, pos + 1);
        std::string err;
        running = control_command(line, err);
        if (!err.empty()) std::cerr << "rbx1-simfw: " << err << "\n";
        if (line.rfind("reset", 0) == 0) {
          to_fw.clear();
          from_fw.clear();
          out_pending.clear();
        }
      }
    }

    if (board.eeprom_dirty && !eeprom_path.empty()) {
      if (!save_eeprom(eeprom_path)) std::cerr << "rbx1-simfw: " << eeprom_path << ": cannot write\n";
    }
    board.eeprom_dirty = false;

    // Sleep until input arrives or about a millisecond passes (the profile tick's period).
    pollfd fds[2] = {{pty.master, POLLIN, 0}, {control_fd, POLLIN, 0}};
    poll(fds, control_fd >= 0 ? 2 : 1, out_pending.empty() ? 1 : 0);
  }
  if (board.eeprom_dirty && !eeprom_path.empty()) save_eeprom(eeprom_path);
  if (log) std::fclose(log);
  if (control_fd >= 0) close(control_fd);
  if (control_keep >= 0) close(control_keep);
  if (!link_path.empty()) ::unlink(link_path.c_str());
  rbx1::sim::close_pty(pty);
  return 0;
}
