// pty_bridge.cpp - a simulated AVR's UART on a pty, bridged in the simulation's own thread.
#include "pty_bridge.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

extern "C" {
#include "sim_io.h"
#include "sim_regbit.h"
}

namespace rbx1::simpty {
namespace {

constexpr avr_cycle_count_t kPumpCycles = 1024;  // the pty is read this often (simulated cycles)
constexpr size_t kBurst = 64;                    // the program's bytes are written out at this many at the latest
constexpr size_t kInLimit = 4096;                // the host's bytes held for the UART before the pty is left to fill
constexpr size_t kOutLimit = 65536;  // the program's bytes held for a host that does not read; the oldest go first

}  // namespace

avr_uart_t* prepare_uart(avr_t* avr, char uart) {
  avr_uart_t* found = nullptr;
  for (avr_io_t* io = avr->io_port; io; io = io->next)
    if (!std::strcmp(io->kind, "uart") && reinterpret_cast<avr_uart_t*>(io)->name == uart)
      found = reinterpret_cast<avr_uart_t*>(io);
  if (!found) return nullptr;
  uint32_t flags = 0;
  avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS(uart), &flags);
  flags &= ~(AVR_UART_FLAG_POLL_SLEEP | AVR_UART_FLAG_STDIO);
  avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS(uart), &flags);
  return found;
}

int open_raw_slave(const std::string& path, std::string& error) {
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY);
  if (fd < 0) {
    error = path + ": " + std::strerror(errno);
    return -1;
  }
  termios tio{};
  tcgetattr(fd, &tio);
  cfmakeraw(&tio);
  tcsetattr(fd, TCSANOW, &tio);
  return fd;
}

bool PtyBridge::open(avr_t* avr, char uart, std::string& error) {
  avr_ = avr;
  uart_ = prepare_uart(avr, uart);
  if (!uart_) {
    error = std::string("the simulated chip has no UART") + uart;
    return false;
  }
  master_fd_ = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
  char name[128];
  if (master_fd_ < 0 || grantpt(master_fd_) != 0 || unlockpt(master_fd_) != 0 ||
      ptsname_r(master_fd_, name, sizeof name) != 0) {
    error = std::string("cannot create a pty: ") + std::strerror(errno);
    return false;
  }
  path_ = name;
  slave_fd_ = open_raw_slave(path_, error);
  if (slave_fd_ < 0) return false;
  uart_in_ = avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_INPUT);
  avr_irq_register_notify(avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUTPUT), &PtyBridge::on_output,
                          this);
  avr_irq_register_notify(avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUT_XON), &PtyBridge::on_xon, this);
  avr_irq_register_notify(avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUT_XOFF), &PtyBridge::on_xoff,
                          this);
  avr_cycle_timer_register(avr_, kPumpCycles, &PtyBridge::on_timer, this);
  return true;
}

void PtyBridge::on_output(avr_irq_t*, uint32_t value, void* param) {
  auto* b = static_cast<PtyBridge*>(param);
  b->out_.push_back(static_cast<uint8_t>(value));
  b->last_out_ = b->avr_->cycle;
  if (b->out_.size() >= kBurst) b->write_out();
}

// The UART raises XON whenever its input FIFO has room (the program read it empty, or enabled its receiver), XOFF
// (filtered: on a change only) with 1 when the FIFO is full and 0 just before an XON.
void PtyBridge::on_xon(avr_irq_t*, uint32_t, void* param) {
  auto* b = static_cast<PtyBridge*>(param);
  b->xon_ = true;
  b->feed();
}

void PtyBridge::on_xoff(avr_irq_t*, uint32_t value, void* param) {
  if (value) static_cast<PtyBridge*>(param)->xon_ = false;
}

avr_cycle_count_t PtyBridge::on_timer(avr_t*, avr_cycle_count_t when, void* param) {
  auto* b = static_cast<PtyBridge*>(param);
  b->pump_output();
  b->take_input();
  return when + kPumpCycles;
}

void PtyBridge::pump() {
  if (master_fd_ < 0) return;
  if (!avr_cycle_timer_status(avr_, &PtyBridge::on_timer, this)) {  // a reset since the last call
    write_out();
    in_.clear();
    in_done_ = 0;
    avr_cycle_timer_register(avr_, kPumpCycles, &PtyBridge::on_timer, this);
  }
  pump_output();
  take_input();
}

void PtyBridge::feed() {
  // A reset turns the receiver off without an XOFF: the UART would drop what it is given until the program enables
  // it again (an XON then). Raising a byte can raise XOFF (the FIFO is full) from inside.
  while (xon_ && avr_regbit_get(avr_, uart_->rxen) && in_done_ < in_.size()) avr_raise_irq(uart_in_, in_[in_done_++]);
  if (in_done_ == in_.size()) {
    in_.clear();
    in_done_ = 0;
  }
}

void PtyBridge::take_input() {
  if (in_.size() - in_done_ < kInLimit) {
    uint8_t buf[512];
    const ssize_t n = ::read(master_fd_, buf, sizeof buf);
    if (n > 0) in_.insert(in_.end(), buf, buf + n);
  }
  feed();
}

void PtyBridge::write_out() {
  if (out_.empty()) return;
  const ssize_t n = ::write(master_fd_, out_.data(), out_.size());
  if (n > 0) out_.erase(out_.begin(), out_.begin() + n);  // the rest once the host has read (EAGAIN: the pty is full)
  if (out_.size() > kOutLimit) out_.erase(out_.begin(), out_.end() - kOutLimit);
}

void PtyBridge::pump_output() {
  const avr_cycle_count_t quiet = 2 * uart_->cycles_per_byte;
  // avr->cycle can go back across a reset: then the line is quiet.
  if (!out_.empty() && (avr_->cycle < last_out_ || avr_->cycle - last_out_ >= quiet)) write_out();
}

int PtyBridge::host_unread() const {
  int n = 0;
  if (slave_fd_ < 0 || ioctl(slave_fd_, FIONREAD, &n) != 0) return 0;
  return n;
}

bool PtyBridge::host_pending() const {
  int n = 0;
  if (master_fd_ >= 0 && ioctl(master_fd_, FIONREAD, &n) == 0 && n > 0) return true;
  return in_done_ < in_.size();
}

void PtyBridge::flush() {
  if (master_fd_ >= 0) write_out();
}

}  // namespace rbx1::simpty
