// gpio_config.cpp - the [gpio] table: estop, start_button, status_led, each optional.
#include "gpio.hpp"

namespace rbx1::gpio {

static void parse_line(rbx1::config::Section s, LineConfig& out, bool input) {
  out.chip = s.string("chip", out.chip);
  out.line = s.string("line", out.line);
  out.active_low = s.boolean("active_low", out.active_low);
  if (input) out.debounce_ms = static_cast<int>(s.integer("debounce_ms", out.debounce_ms, 0, 1000));
  if (out.line.empty()) s.errors().add(s.path() + ".line", "required (a line name or an offset)");
  s.reject_unknown();
}

void parse_gpio_config(rbx1::config::Section gpio, GpioConfig& out) {
  if (gpio.has("estop")) parse_line(gpio.section("estop"), out.estop, true);
  if (gpio.has("start_button")) parse_line(gpio.section("start_button"), out.start_button, true);
  if (gpio.has("status_led")) parse_line(gpio.section("status_led"), out.status_led, false);
  gpio.reject_unknown();
}

}  // namespace rbx1::gpio
