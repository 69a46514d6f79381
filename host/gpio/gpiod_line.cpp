// gpiod_line.cpp - the real backends on libgpiod v1: a both-edges input and an output line.
#include <cerrno>
#include <cstring>
#include <gpiod.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "gpio.hpp"

namespace rbx1::gpio {

namespace {

constexpr const char* kConsumer = "rbx1d";

bool is_offset(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

std::string where(const LineConfig& c) {
  return (c.chip.empty() ? std::string("any chip") : "chip '" + c.chip + "'") + " line '" + c.line + "'";
}

// Finds the chip and line of c. On success the caller owns *chip (close it after releasing the line).
gpiod_line* find_line(const std::string& name, const LineConfig& c, gpiod_chip** chip, std::string& error) {
  *chip = nullptr;
  gpiod_line* line = nullptr;
  if (c.chip.empty()) {
    if (is_offset(c.line)) {
      error = name + ": line offset " + c.line + " needs a chip";
      return nullptr;
    }
    line = gpiod_line_find(c.line.c_str());  // searches every chip by line name
    if (!line) {
      int e = errno;
      error = name + ": no gpio line named '" + c.line + "' on any chip";
      if (e && e != ENOENT) error += std::string(" (") + std::strerror(e) + ")";
      return nullptr;
    }
    *chip = gpiod_line_get_chip(line);
    return line;
  }
  *chip = gpiod_chip_open_lookup(c.chip.c_str());
  if (!*chip) {
    error = name + ": gpio chip '" + c.chip + "': " + std::strerror(errno);
    return nullptr;
  }
  line = is_offset(c.line) ? gpiod_chip_get_line(*chip, static_cast<unsigned>(std::stoul(c.line)))
                           : gpiod_chip_find_line(*chip, c.line.c_str());
  if (!line) {
    error = name + ": " + where(c) + " not found";
    gpiod_chip_close(*chip);
    *chip = nullptr;
  }
  return line;
}

class GpiodEdgeSource : public EdgeSource {
 public:
  GpiodEdgeSource(gpiod_chip* chip, gpiod_line* line, std::string text, int wake)
      : chip_(chip), line_(line), text_(std::move(text)), wake_(wake) {}
  ~GpiodEdgeSource() override {
    gpiod_line_release(line_);
    gpiod_chip_close(chip_);
    ::close(wake_);
  }
  int level() override {
    int v = gpiod_line_get_value(line_);
    return v < 0 ? -errno : v;
  }
  int wait(int64_t timeout_ns, std::vector<RawEdge>& out) override {
    pollfd fds[2] = {{gpiod_line_event_get_fd(line_), POLLIN, 0}, {wake_, POLLIN, 0}};
    int timeout_ms = timeout_ns < 0 ? -1 : static_cast<int>((timeout_ns + 999999) / 1000000);
    int n = poll(fds, 2, timeout_ms);
    if (n < 0) return errno == EINTR ? 0 : -errno;
    if (fds[1].revents) {
      uint64_t v;
      if (::read(wake_, &v, sizeof v) < 0) spdlog::debug("gpio: eventfd read: {}", std::strerror(errno));
    }
    if (fds[0].revents & POLLIN) {
      gpiod_line_event ev;
      if (gpiod_line_event_read(line_, &ev) < 0) return -errno;
      out.push_back({ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE,
                     int64_t(ev.ts.tv_sec) * 1000000000 + ev.ts.tv_nsec});
    }
    return 0;
  }
  void wake() override {
    uint64_t one = 1;
    if (::write(wake_, &one, sizeof one) < 0) spdlog::debug("gpio: eventfd write: {}", std::strerror(errno));
  }
  std::string describe() const override { return text_; }

 private:
  gpiod_chip* chip_;
  gpiod_line* line_;
  std::string text_;
  int wake_;
};

class GpiodOutputLine : public OutputLine {
 public:
  GpiodOutputLine(gpiod_chip* chip, gpiod_line* line, bool active_low, std::string text)
      : chip_(chip), line_(line), active_low_(active_low), text_(std::move(text)) {}
  ~GpiodOutputLine() override {
    gpiod_line_set_value(line_, active_low_ ? 1 : 0);  // off
    gpiod_line_release(line_);
    gpiod_chip_close(chip_);
  }
  int set(bool on) override { return gpiod_line_set_value(line_, on != active_low_ ? 1 : 0) < 0 ? -errno : 0; }
  std::string describe() const override { return text_; }

 private:
  gpiod_chip* chip_;
  gpiod_line* line_;
  bool active_low_;
  std::string text_;
};

}  // namespace

std::unique_ptr<EdgeSource> open_gpiod_input(const std::string& name, const LineConfig& c, std::string& error) {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = find_line(name, c, &chip, error);
  if (!line) return nullptr;
  // Polarity is applied by InputWatcher, not by the kernel, so the real and simulated paths are the same.
  if (gpiod_line_request_both_edges_events(line, kConsumer) < 0) {
    error = name + ": cannot request " + where(c) + " for edge events: " + std::strerror(errno);
    gpiod_chip_close(chip);
    return nullptr;
  }
  int wake = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake < 0) {
    error = name + ": eventfd: " + std::strerror(errno);
    gpiod_line_release(line);
    gpiod_chip_close(chip);
    return nullptr;
  }
  std::string text = std::string(gpiod_chip_name(chip)) + ":" + std::to_string(gpiod_line_offset(line));
  return std::make_unique<GpiodEdgeSource>(chip, line, text, wake);
}

std::unique_ptr<InputWatcher> open_input(const std::string& name, const LineConfig& c, std::string& error) {
  auto source = open_gpiod_input(name, c, error);
  if (!source) return nullptr;
  return std::make_unique<InputWatcher>(name, std::move(source), c.active_low, c.debounce_ms);
}

std::unique_ptr<OutputLine> open_output(const std::string& name, const LineConfig& c, std::string& error) {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = find_line(name, c, &chip, error);
  if (!line) return nullptr;
  if (gpiod_line_request_output(line, kConsumer, c.active_low ? 1 : 0) < 0) {
    error = name + ": cannot request " + where(c) + " as an output: " + std::strerror(errno);
    gpiod_chip_close(chip);
    return nullptr;
  }
  std::string text = std::string(gpiod_chip_name(chip)) + ":" + std::to_string(gpiod_line_offset(line));
  return std::make_unique<GpiodOutputLine>(chip, line, c.active_low, text);
}

}  // namespace rbx1::gpio
