// link_session.cpp - a Link's session: opening the port, the HELLO handshake (a board in its bootloader, a
// version 3 firmware), closing, and reconnecting after the device vanished.
#include "link.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <sys/eventfd.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "serial_port.hpp"

namespace rbx1::link {

using Clock = std::chrono::steady_clock;

int Link::open(const LinkConfig& config, std::string& error) {
  set_timing(config.timeout_ms, config.retries);
  set_window(config.window);
  set_boot_wait(config.boot_wait_ms);
  return open(config.port, config.baud, error);
}

int Link::open(const std::string& port, int baud, std::string& error) {
  close();
  path_ = name_ = port;
  baud_ = baud;
  int fd = open_serial(port, baud, error);
  if (fd < 0) return fd;
  return attach(fd, error);
}

int Link::open_fd(int fd, const std::string& name, std::string& error) {
  close();
  path_.clear();
  name_ = name;
  baud_ = 0;
  return attach(fd, error);
}

int Link::attach(int fd, std::string& error) {
  int wake = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake < 0) {
    int e = errno;
    ::close(fd);
    error = name_ + ": eventfd: " + std::strerror(e);
    return -e;
  }
  {
    std::scoped_lock lock(write_mu_, state_mu_);
    fd_ = fd;
    wake_fd_ = wake;
    gone_error_ = 0;
    connected_ = true;
  }
  rbx1_decoder_init(&decoder_, &Link::on_frame, &Link::on_reject, this);
  recent_.clear();
  v3_seen_ = false;
  reader_ = std::thread(&Link::reader_loop, this, fd, wake);
  int r = handshake(error);
  if (r < 0) detach();
  return r;
}

// A Mega that the open reset (DTR) or that was just plugged in sits in its stk500v2 bootloader for 0.83 s; a byte
// arriving then (our HELLO) keeps it there until 5.2 s pass without one (measured: tools/flashsim/README.md).
// So after an unanswered HELLO exchange the link keeps quiet this long before asking again; repeating HELLO
// would hold the board in its bootloader forever.
constexpr auto kBootloaderQuiet = std::chrono::milliseconds(6000);

int Link::handshake(std::string& error) {
  rbx1_hello_resp h{};
  auto deadline = Clock::now() + std::chrono::milliseconds(boot_wait_ms_.load());
  handshaking_ = true;
  int r = hello(h);
  while (r == -ETIMEDOUT && !v3_seen_ && Clock::now() < deadline) {
    auto quiet = std::min<Clock::duration>(kBootloaderQuiet, deadline - Clock::now());
    spdlog::info("{}: no HELLO answer yet; quiet for {} ms so a board in its bootloader starts the firmware", name_,
                 std::chrono::duration_cast<std::chrono::milliseconds>(quiet).count());
    std::this_thread::sleep_for(quiet);
    r = hello(h);
  }
  handshaking_ = false;
  if (r == -ETIMEDOUT && v3_seen_) {
    error = name_ + ": firmware speaks protocol version 3 (CRC-16 frames: it NAKs every frame of ours), this host " +
            std::to_string(RBX1_PROTO_VERSION) + "; flash the matching firmware: rbx1-flash " + name_ +
            " (from a checkout: make flash PORT=" + name_ + ")";
    return -EPROTO;
  }
  if (r == -EPROTO) {
    error = name_ + ": firmware speaks protocol version " + std::to_string(h.proto_version) + ", this host " +
            std::to_string(RBX1_PROTO_VERSION) + "; flash the matching firmware: rbx1-flash " + name_ +
            " (from a checkout: make flash PORT=" + name_ + ")";
    return r;
  }
  if (r < 0) {
    error = name_ + ": no HELLO response (" + std::strerror(-r) + ")";
    return r;
  }
  if (h.status != RBX1_OK) {
    error = name_ + ": HELLO refused: " + rbx1_status_name(h.status);
    return -EPROTO;
  }
  spdlog::info("{}: firmware {}.{}.{}, {} joints, queue {}, window {}, capabilities 0x{:04x}, continuing at seq {}",
               name_, h.fw_major, h.fw_minor, h.fw_patch, h.joints, h.queue_size, h.window, h.capabilities,
               next_seq());
  return 0;
}

void Link::detach() {
  int fd, wake;
  {
    std::scoped_lock lock(write_mu_, state_mu_);
    fd = fd_;
    wake = wake_fd_;
    fd_ = wake_fd_ = -1;
    connected_ = false;
    if (!gone_error_) gone_error_ = ENOTCONN;
  }
  state_cv_.notify_all();
  if (wake >= 0) {
    uint64_t one = 1;
    if (::write(wake, &one, sizeof one) < 0) spdlog::debug("{}: eventfd write: {}", name_, std::strerror(errno));
  }
  if (reader_.joinable()) reader_.join();
  if (fd >= 0) ::close(fd);
  if (wake >= 0) ::close(wake);
}

void Link::close() {
  stop_heartbeat();
  std::lock_guard<std::mutex> lock(request_mu_);
  detach();
}

int Link::reconnect(std::string& error) {
  if (path_.empty()) {
    error = name_ + ": opened from an fd, cannot be reopened";
    return -EOPNOTSUPP;
  }
  {
    std::lock_guard<std::mutex> lock(request_mu_);
    detach();
  }
  int fd = open_serial(path_, baud_, error);
  if (fd < 0) return fd;
  int r = attach(fd, error);
  if (r == 0) {
    counters_.reconnects++;
    spdlog::info("{}: reconnected", name_);
  }
  return r;
}

int Link::wait_reconnect(int timeout_ms, std::string& error) {
  auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    int r = reconnect(error);
    if (r == 0 || Clock::now() >= deadline) return r;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

}  // namespace rbx1::link
