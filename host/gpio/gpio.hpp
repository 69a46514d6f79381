// gpio.hpp - e-stop, start button and status LED: a thin seam over libgpiod v1, with a simulated backend.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "config.hpp"

namespace rbx1::gpio {

// One line: which chip, which line, polarity, debounce.
struct LineConfig {
  std::string chip;         // "gpiochip0", "/dev/gpiochip0", a chip label or number; empty: find line by name
  std::string line;         // a line name ("ESTOP") or an offset ("17"); empty: not configured
  bool active_low = false;  // true: the line reads 0 when the input is active (a normally-closed e-stop)
  int debounce_ms = 10;     // inputs only
  bool configured() const { return !line.empty(); }
};

// The [gpio] table; every entry is optional, e.g. estop = { chip = "gpiochip0", line = "ESTOP" }.
struct GpioConfig {
  LineConfig estop, start_button, status_led;
};
void parse_gpio_config(rbx1::config::Section gpio, GpioConfig& out);

// A raw level change of the physical line, as the backend saw it.
struct RawEdge {
  bool level;            // physical level after the edge
  int64_t timestamp_ns;  // CLOCK_MONOTONIC
};

// The seam: where raw edges come from (libgpiod, or a test).
class EdgeSource {
 public:
  virtual ~EdgeSource() = default;
  virtual int level() = 0;  // current physical level 0/1, or a negative errno
  // Waits up to timeout_ns (-1: forever) for edges and appends them. 0, or a negative errno.
  virtual int wait(int64_t timeout_ns, std::vector<RawEdge>& out) = 0;
  virtual void wake() = 0;  // makes a pending wait() return (stop)
  virtual std::string describe() const = 0;
};

// Edges injected by tests (or a simulator); level changes are timestamped at injection unless given.
class SimEdgeSource : public EdgeSource {
 public:
  explicit SimEdgeSource(bool initial_level = false) : level_(initial_level) {}
  void inject(bool level);
  void inject(bool level, int64_t timestamp_ns);
  int level() override;
  int wait(int64_t timeout_ns, std::vector<RawEdge>& out) override;
  void wake() override;
  std::string describe() const override { return "simulated"; }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<RawEdge> edges_;
  bool level_;
  bool woken_ = false;
};

// Leading-edge debounce: the first edge that changes the state counts at once (an e-stop must not wait);
// edges during the following debounce window are ignored, and when the window ends the line's level is
// taken again, so chatter gives one event and a press shorter than the window still gives press + release.
class Debouncer {
 public:
  Debouncer(int64_t window_ns, bool initial) : window_ns_(window_ns), state_(initial), raw_(initial) {}
  bool edge(bool level, int64_t t_ns);  // true when the debounced state changed now
  bool settle(int64_t t_ns);            // call at deadline(); true when the state changed
  int64_t deadline() const { return pending_ ? until_ns_ : -1; }
  bool state() const { return state_; }

 private:
  int64_t window_ns_;
  bool state_, raw_;
  bool pending_ = false;
  int64_t until_ns_ = INT64_MIN;
};

struct InputEvent {
  std::string name;      // "estop", "start_button"
  bool active;           // after active-low
  int64_t timestamp_ns;  // CLOCK_MONOTONIC of the edge that caused it
};
using InputCallback = std::function<void(const InputEvent&)>;

// Watches one input on its own thread; callbacks run on that thread.
class InputWatcher {
 public:
  InputWatcher(std::string name, std::unique_ptr<EdgeSource> source, bool active_low, int debounce_ms);
  ~InputWatcher();
  int start(InputCallback callback);  // 0 or a negative errno (the line cannot be read)
  void stop();
  bool active() const { return active_.load(); }  // debounced
  std::string describe() const;

 private:
  void loop();
  std::string name_;
  std::unique_ptr<EdgeSource> source_;
  bool active_low_;
  int64_t window_ns_;
  InputCallback callback_;
  std::thread thread_;
  std::atomic<bool> stop_{false}, active_{false};
};

// An output line (status LED).
class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual int set(bool on) = 0;  // logical value (active-low applied); 0 or a negative errno
  virtual std::string describe() const = 0;
};

class SimOutputLine : public OutputLine {
 public:
  int set(bool on) override {
    value_ = on;
    ++writes_;
    return 0;
  }
  std::string describe() const override { return "simulated"; }
  bool value() const { return value_; }
  int writes() const { return writes_; }

 private:
  std::atomic<bool> value_{false};
  std::atomic<int> writes_{0};
};

// libgpiod v1 backends. null + error "NAME: reason" when the chip or line cannot be had.
std::unique_ptr<EdgeSource> open_gpiod_input(const std::string& name, const LineConfig& c, std::string& error);
std::unique_ptr<InputWatcher> open_input(const std::string& name, const LineConfig& c, std::string& error);
std::unique_ptr<OutputLine> open_output(const std::string& name, const LineConfig& c, std::string& error);

int64_t monotonic_ns();

}  // namespace rbx1::gpio
