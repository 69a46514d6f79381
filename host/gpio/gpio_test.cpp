// gpio_test.cpp - debounce, active-low, the simulated backend, config errors, and a real gpiochip when present.
#include "gpio.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <gpiod.h>

#include <gtest/gtest.h>

using namespace rbx1::gpio;
using namespace std::chrono;

namespace {

constexpr int64_t kMs = 1000000;

// Collects the watcher's events (they arrive on its thread).
struct Recorder {
  std::mutex mu;
  std::condition_variable cv;
  std::vector<InputEvent> events;
  InputCallback callback() {
    return [this](const InputEvent& e) {
      std::lock_guard<std::mutex> lock(mu);
      events.push_back(e);
      cv.notify_all();
    };
  }
  std::vector<InputEvent> wait_for(size_t n, milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, timeout, [&] { return events.size() >= n; });
    return events;
  }
};

}  // namespace

TEST(Debouncer, ChatterGivesOneEvent) {
  Debouncer d(10 * kMs, false);
  EXPECT_TRUE(d.edge(true, 100 * kMs));  // leading edge counts at once
  EXPECT_FALSE(d.edge(false, 101 * kMs));
  EXPECT_FALSE(d.edge(true, 102 * kMs));
  EXPECT_FALSE(d.edge(false, 103 * kMs));
  EXPECT_FALSE(d.edge(true, 104 * kMs));
  EXPECT_EQ(d.deadline(), 110 * kMs);
  EXPECT_FALSE(d.settle(109 * kMs));  // not yet
  EXPECT_FALSE(d.settle(110 * kMs));  // settled where it already was
  EXPECT_TRUE(d.state());
  EXPECT_EQ(d.deadline(), -1);
}

TEST(Debouncer, ShortPulseGivesPressAndRelease) {
  Debouncer d(10 * kMs, false);
  EXPECT_TRUE(d.edge(true, 0));
  EXPECT_FALSE(d.edge(false, 2 * kMs));
  EXPECT_TRUE(d.settle(10 * kMs));
  EXPECT_FALSE(d.state());
  EXPECT_FALSE(d.edge(true, 15 * kMs));  // within the new window after the release
  EXPECT_TRUE(d.settle(20 * kMs));
  EXPECT_TRUE(d.state());
}

TEST(Debouncer, ZeroWindowPassesEveryChange) {
  Debouncer d(0, false);
  EXPECT_TRUE(d.edge(true, 1));
  EXPECT_FALSE(d.edge(true, 2));  // same level again: no change
  EXPECT_TRUE(d.edge(false, 3));
}

TEST(InputWatcher, ChatteringPressIsOneEventWithTheFirstEdgesTime) {
  auto src = std::make_unique<SimEdgeSource>(false);
  SimEdgeSource* sim = src.get();
  InputWatcher w("estop", std::move(src), false, 20);
  Recorder rec;
  ASSERT_EQ(w.start(rec.callback()), 0);
  EXPECT_FALSE(w.active());
  int64_t t0 = monotonic_ns();
  for (int i = 0; i < 7; ++i) sim->inject(i % 2 == 0, t0 + i * 500000);  // 7 edges in 3 ms, ending high
  auto ev = rec.wait_for(1, milliseconds(500));
  std::this_thread::sleep_for(milliseconds(60));  // past the window: no second event may come
  ev = rec.wait_for(2, milliseconds(0));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].name, "estop");
  EXPECT_TRUE(ev[0].active);
  EXPECT_EQ(ev[0].timestamp_ns, t0);
  EXPECT_TRUE(w.active());
  // Release with chatter: one event.
  int64_t t1 = monotonic_ns();
  for (int i = 0; i < 5; ++i) sim->inject(i % 2 != 0 ? true : false, t1 + i * 400000);
  std::this_thread::sleep_for(milliseconds(60));
  ev = rec.wait_for(2, milliseconds(100));
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_FALSE(ev[1].active);
  EXPECT_FALSE(w.active());
  w.stop();
}

TEST(InputWatcher, GlitchShorterThanTheWindowStillReleases) {
  auto src = std::make_unique<SimEdgeSource>(false);
  SimEdgeSource* sim = src.get();
  InputWatcher w("start_button", std::move(src), false, 15);
  Recorder rec;
  ASSERT_EQ(w.start(rec.callback()), 0);
  sim->inject(true);
  sim->inject(false);
  auto ev = rec.wait_for(2, milliseconds(500));
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_TRUE(ev[0].active);
  EXPECT_FALSE(ev[1].active);
  EXPECT_GE(ev[1].timestamp_ns - ev[0].timestamp_ns, 15 * kMs);
  EXPECT_FALSE(w.active());
}

TEST(InputWatcher, ActiveLowInvertsTheLine) {
  auto src = std::make_unique<SimEdgeSource>(true);  // normally-closed e-stop: line high when released
  SimEdgeSource* sim = src.get();
  InputWatcher w("estop", std::move(src), true, 5);
  Recorder rec;
  ASSERT_EQ(w.start(rec.callback()), 0);
  EXPECT_FALSE(w.active());
  sim->inject(false);  // pressed (or the wire is cut): line goes low
  auto ev = rec.wait_for(1, milliseconds(500));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_TRUE(ev[0].active);
  EXPECT_TRUE(w.active());
}

TEST(InputWatcher, CallbackLatencyIsShort) {
  auto src = std::make_unique<SimEdgeSource>(false);
  SimEdgeSource* sim = src.get();
  InputWatcher w("estop", std::move(src), false, 10);
  std::atomic<int64_t> seen{0};
  ASSERT_EQ(w.start([&](const InputEvent&) { seen = monotonic_ns(); }), 0);
  int64_t t0 = monotonic_ns();
  sim->inject(true, t0);
  for (int i = 0; i < 500 && !seen; ++i) std::this_thread::sleep_for(microseconds(200));
  ASSERT_NE(seen.load(), 0);
  EXPECT_LT(seen - t0, 50 * kMs);
  w.stop();
}

TEST(InputWatcher, StopsPromptlyWithoutEdges) {
  InputWatcher w("estop", std::make_unique<SimEdgeSource>(false), false, 10);
  ASSERT_EQ(w.start(nullptr), 0);
  auto t0 = steady_clock::now();
  w.stop();
  EXPECT_LT(steady_clock::now() - t0, milliseconds(100));
}

TEST(SimOutputLine, RecordsWrites) {
  SimOutputLine led;
  EXPECT_EQ(led.set(true), 0);
  EXPECT_TRUE(led.value());
  EXPECT_EQ(led.set(false), 0);
  EXPECT_FALSE(led.value());
  EXPECT_EQ(led.writes(), 2);
}

TEST(GpioConfig, ParsesAllThreeLines) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text(
      "[gpio]\nestop = { chip = \"gpiochip0\", line = \"ESTOP\", active_low = true, debounce_ms = 5 }\n"
      "start_button = { line = \"17\", chip = \"/dev/gpiochip1\" }\n"
      "[gpio.status_led]\nchip = \"pinctrl-bcm2835\"\nline = \"LED\"\n",
      errors);
  rbx1::config::Section root(&t, "", errors);
  GpioConfig c;
  parse_gpio_config(root.section("gpio"), c);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_EQ(c.estop.chip, "gpiochip0");
  EXPECT_EQ(c.estop.line, "ESTOP");
  EXPECT_TRUE(c.estop.active_low);
  EXPECT_EQ(c.estop.debounce_ms, 5);
  EXPECT_EQ(c.start_button.line, "17");
  EXPECT_EQ(c.start_button.debounce_ms, 10);
  EXPECT_FALSE(c.start_button.active_low);
  EXPECT_EQ(c.status_led.chip, "pinctrl-bcm2835");
  EXPECT_TRUE(c.status_led.configured());
}

TEST(GpioConfig, AbsentTableMeansNoGpio) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text("[link]\nport = \"x\"\n", errors);
  rbx1::config::Section root(&t, "", errors);
  GpioConfig c;
  parse_gpio_config(root.section("gpio"), c);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_FALSE(c.estop.configured());
  EXPECT_FALSE(c.start_button.configured());
  EXPECT_FALSE(c.status_led.configured());
}

TEST(GpioConfig, ErrorsNameTheKey) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text(
      "[gpio]\nestop = { chip = \"gpiochip0\", debounce_ms = 5000 }\nstatus_led = { line = \"X\", debounce_ms = 3 }\n"
      "buzzer = { line = \"1\" }\n",
      errors);
  rbx1::config::Section root(&t, "", errors);
  GpioConfig c;
  parse_gpio_config(root.section("gpio"), c);
  ASSERT_EQ(errors.messages().size(), 4u) << errors.joined();
  EXPECT_EQ(errors.messages()[0].rfind("gpio.estop.debounce_ms: must be within [0, 1000]", 0), 0u);
  EXPECT_EQ(errors.messages()[1], "gpio.estop.line: required (a line name or an offset)");
  EXPECT_EQ(errors.messages()[2], "gpio.status_led.debounce_ms: unknown key");
  EXPECT_EQ(errors.messages()[3], "gpio.buzzer: unknown key");
}

TEST(Gpiod, MissingChipOrLineIsAClearError) {
  std::string error;
  EXPECT_EQ(open_input("estop", LineConfig{"gpiochip97", "ESTOP", false, 10}, error), nullptr);
  EXPECT_EQ(error.rfind("estop: gpio chip 'gpiochip97': ", 0), 0u) << error;
  EXPECT_EQ(open_output("status_led", LineConfig{"", "RBX1_NO_SUCH_LINE", false, 0}, error), nullptr);
  EXPECT_EQ(error, "status_led: no gpio line named 'RBX1_NO_SUCH_LINE' on any chip");
  EXPECT_EQ(open_input("start_button", LineConfig{"", "4", false, 10}, error), nullptr);
  EXPECT_EQ(error, "start_button: line offset 4 needs a chip");
}

// On a machine with a gpiochip (a Raspberry Pi, or gpio-sim loaded): the chip opens and reports its lines.
TEST(Gpiod, RealChipWhenPresent) {
  std::string first;
  for (const auto& e : std::filesystem::directory_iterator("/dev"))
    if (e.path().filename().string().rfind("gpiochip", 0) == 0) first = e.path().string();
  if (first.empty()) GTEST_SKIP() << "no /dev/gpiochip* on this machine: real-GPIO test skipped";
  gpiod_chip* chip = gpiod_chip_open_lookup(first.c_str());
  ASSERT_NE(chip, nullptr) << first << ": " << std::strerror(errno);
  EXPECT_GT(gpiod_chip_num_lines(chip), 0u);
  std::string error;
  // Offset past the last line: a clear error, not a crash.
  LineConfig bad{first, std::to_string(gpiod_chip_num_lines(chip) + 5), false, 10};
  EXPECT_EQ(open_input("estop", bad, error), nullptr);
  EXPECT_NE(error.find("not found"), std::string::npos) << error;
  gpiod_chip_close(chip);
}

// Real edge events through libgpiod: a gpio-sim chip (configfs; Linux 5.17+ with CONFIG_GPIO_SIM, as root) is
// made for the test, its line 0 pulled up and down from sysfs, and the e-stop watcher over the libgpiod backend
// must report the press and the release. Skips, saying why, where gpio-sim cannot be had.
namespace {
bool write_file(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return false;
  bool ok = std::fputs(text.c_str(), f) >= 0;
  return std::fclose(f) == 0 && ok;
}
std::string read_word(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (!f) return "";
  char buf[128] = {0};
  if (!std::fgets(buf, sizeof buf, f)) buf[0] = 0;
  std::fclose(f);
  std::string s(buf);
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}
}  // namespace

TEST(Gpiod, EdgesFromAGpioSimChipReachTheWatcher) {
  const std::string root = "/sys/kernel/config/gpio-sim";
  if (!std::filesystem::is_directory(root))
    GTEST_SKIP() << "no " << root << " (gpio-sim not loaded or configfs not mounted): real-edge test skipped";
  const std::string dev = root + "/rbx1-test-" + std::to_string(getpid());
  const std::string bank = dev + "/bank0";
  ASSERT_TRUE(std::filesystem::create_directory(dev)) << dev;
  struct Cleanup {
    std::string dev, bank;
    ~Cleanup() {
      write_file(dev + "/live", "0");
      std::filesystem::remove(bank);
      std::filesystem::remove(dev);
    }
  } cleanup{dev, bank};
  ASSERT_TRUE(std::filesystem::create_directory(bank));
  ASSERT_TRUE(write_file(bank + "/num_lines", "4"));
  ASSERT_TRUE(write_file(dev + "/live", "1")) << "cannot make the gpio-sim chip live";
  std::string chip = read_word(bank + "/chip_name"), platform = read_word(dev + "/dev_name");
  ASSERT_FALSE(chip.empty());
  const std::string pull = "/sys/devices/platform/" + platform + "/" + chip + "/sim_gpio0/pull";
  ASSERT_TRUE(write_file(pull, "pull-down"));

  std::string error;
  auto w = open_input("estop", LineConfig{chip, "0", false, 0}, error);
  ASSERT_NE(w, nullptr) << error;
  Recorder rec;
  ASSERT_EQ(w->start(rec.callback()), 0);
  int64_t t0 = monotonic_ns();
  ASSERT_TRUE(write_file(pull, "pull-up"));  // pressed
  auto ev = rec.wait_for(1, milliseconds(2000));
  ASSERT_EQ(ev.size(), 1u) << "no event from the kernel's edge";
  EXPECT_TRUE(ev[0].active);
  EXPECT_EQ(ev[0].name, "estop");
  EXPECT_GE(ev[0].timestamp_ns, t0) << "the kernel's edge time is CLOCK_MONOTONIC";
  ASSERT_TRUE(write_file(pull, "pull-down"));  // released
  ev = rec.wait_for(2, milliseconds(2000));
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_FALSE(ev[1].active);
  w->stop();
}
