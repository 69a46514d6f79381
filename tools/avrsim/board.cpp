// board.cpp - loading the firmware into simavr, the UART pty bridge, EEPROM persistence and input pins.
#include "board.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" {
#include "avr_eeprom.h"
#include "avr_extint.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_elf.h"
#include "sim_io.h"
}

#include "pinmap.hpp"

namespace rbx1::avrsim {
namespace {

constexpr uint32_t kFrequency = 16000000;
constexpr size_t kEepromSize = 4096;

// simavr logs "info" lines on stdout, where our first line must be the pty path: everything goes to stderr.
void log_to_stderr(avr_t* avr, const int level, const char* format, va_list ap) {
  if (level <= (avr ? avr->log : static_cast<int>(LOG_WARNING))) std::vfprintf(stderr, format, ap);
}

// simavr's raw sleep callback usleep()s through SLEEP instructions; pacing is done by the run loop instead.
void no_sleep(avr_t*, avr_cycle_count_t) {}

avr_irq_t* pin_irq(avr_t* avr, PortPin p) { return avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(p.port), p.bit); }

}  // namespace

bool Board::open(const std::string& elf, const std::string& eeprom_file, std::string& error) {
  avr_global_logger_set(log_to_stderr);
  elf_firmware_t fw;
  std::memset(&fw, 0, sizeof fw);
  if (access(elf.c_str(), R_OK) != 0 || elf_read_firmware(elf.c_str(), &fw) != 0) {
    error = elf + ": cannot read the firmware ELF";
    return false;
  }
  std::snprintf(fw.mmcu, sizeof fw.mmcu, "atmega2560");
  fw.frequency = kFrequency;
  avr_ = avr_make_mcu_by_name(fw.mmcu);
  if (!avr_) {
    error = "simavr has no atmega2560 core";
    return false;
  }
  avr_init(avr_);
  avr_->sleep = no_sleep;
  // A pin held low on INT0..7 would otherwise be polled every cycle (simavr's "strict" low-level trigger), even
  // with the interrupt disabled: that slowed the simulation twenty-fold. Low level now acts as a falling edge.
  for (uint8_t i = 0; i < 8; i++) avr_extint_set_strict_lvl_trig(avr_, i, 0);
  avr_load_firmware(avr_, &fw);
  avr_->frequency = kFrequency;

  eeprom_file_ = eeprom_file;
  if (!eeprom_file_.empty()) {
    std::ifstream in(eeprom_file_, std::ios::binary);
    if (in) {
      std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (bytes.size() > kEepromSize) bytes.resize(kEepromSize);
      if (!bytes.empty()) {
        avr_eeprom_desc_t d{bytes.data(), 0, static_cast<uint32_t>(bytes.size())};
        avr_ioctl(avr_, AVR_IOCTL_EEPROM_SET, &d);
      }
    }
  }

  // The pty is bridged in this thread (tools/simpty), between slices of simulated time: simavr's uart_pty moves
  // bytes in a thread of its own, which a loaded machine held up while simulated time ran on (the firmware's
  // answers came late by its clock, --hold-for-host saw nothing unread), and its writes are unchecked.
  bridge_ = std::make_unique<simpty::PtyBridge>();
  if (!bridge_->open(avr_, '0', error)) return false;
  pty_name_ = bridge_->path();
  uart0_ = bridge_->uart();
  drive_inputs(true);
  return true;
}

void Board::set_uart_timing(uint32_t forced_baud) {
  if (!uart0_) return;
  avr_cycle_count_t per_bit;
  if (forced_baud) {
    per_bit = (kFrequency + forced_baud / 2) / forced_baud;
  } else {
    const uint32_t ubrr = avr_->data[0xC4] | ((avr_->data[0xC5] & 0x0F) << 8);  // UBRR0L, UBRR0H
    const bool u2x = avr_->data[0xC0] & 0x02;                                     // UCSR0A.U2X0
    per_bit = (ubrr + 1) * (u2x ? 8 : 16);
  }
  uart0_->cycles_per_byte = per_bit * 10;  // start, 8 data, stop
}

// An input is held at its level as an "external" pull in simavr: otherwise simavr's model of the internal
// pull-up would pull it back high on every PORT write of that port.
void Board::drive(PortPin p, uint8_t level, bool force) {
  Pull& pull = pulls_[static_cast<uint8_t>(p.port - 'A') & 15];
  pull.mask |= 1u << p.bit;
  pull.value = level ? (pull.value | (1u << p.bit)) : (pull.value & ~(1u << p.bit));
  avr_ioport_external_t ext{};
  ext.name = static_cast<unsigned long>(p.port) & 0x7F;
  ext.mask = pull.mask;
  ext.value = pull.value;
  avr_ioctl(avr_, AVR_IOCTL_IOPORT_SET_EXTERNAL(p.port), &ext);
  avr_irq_t* irq = pin_irq(avr_, p);
  // After a reset the PIN register is zeroed while the IRQ remembers its old level: toggle to force it.
  if (force) avr_raise_irq(irq, !level);
  avr_raise_irq(irq, level);
}

void Board::drive_inputs(bool force) {
  for (int j = 0; j < RBX1_JOINTS; j++) drive(kJoints[j].limit, limits_[j] ? kLimitActive : !kLimitActive, force);
  drive(kEstop, estop_ ? kEstopActive : !kEstopActive, force);
}

void Board::set_estop(bool asserted) {
  estop_ = asserted;
  drive(kEstop, asserted ? kEstopActive : !kEstopActive, false);
}

void Board::set_limit(int joint, bool triggered) {
  limits_[joint] = triggered;
  drive(kJoints[joint].limit, triggered ? kLimitActive : !kLimitActive, false);
}

void Board::reset() {
  std::string ignored;
  save_eeprom(ignored);
  avr_reset(avr_);
  drive_inputs(true);
}

bool Board::save_eeprom(std::string& error) {
  if (eeprom_file_.empty() || !avr_) return true;
  std::vector<uint8_t> bytes(kEepromSize);
  avr_eeprom_desc_t d{nullptr, 0, static_cast<uint32_t>(kEepromSize)};
  avr_ioctl(avr_, AVR_IOCTL_EEPROM_GET, &d);  // simavr 1.6 answers -1 even on success: check the copy instead
  if (!d.ee) {
    error = "cannot read the simulated EEPROM";
    return false;
  }
  std::memcpy(bytes.data(), d.ee, kEepromSize);
  std::string tmp = eeprom_file_ + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (!out) {
      error = tmp + ": " + std::strerror(errno);
      return false;
    }
  }
  if (std::rename(tmp.c_str(), eeprom_file_.c_str()) != 0) {
    error = eeprom_file_ + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

int Board::host_unread() const { return bridge_->host_unread(); }

bool Board::host_pending() const { return bridge_->host_pending(); }

void Board::pump() { bridge_->pump(); }

void Board::flush() {
  if (bridge_) bridge_->flush();
}

}  // namespace rbx1::avrsim
