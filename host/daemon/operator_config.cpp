// operator_config.cpp - reads and range-checks the [operator] table.
#include "operator_config.hpp"

#include "markers.hpp"

namespace rbx1::daemon {

void parse_operator_config(config::Section s, OperatorConfig& out) {
  out.jog_max_deg = s.number("jog_max_deg", out.jog_max_deg, 0.01, 180);
  out.jog_max_mm = s.number("jog_max_mm", out.jog_max_mm, 0.1, 1000);
  out.background_frames = int(s.integer("background_frames", out.background_frames, 1, 64));
  out.marker_dictionary = s.string("marker_dictionary", out.marker_dictionary);
  if (!calib::marker_dictionary_known(out.marker_dictionary))
    s.errors().add(s.path() + ".marker_dictionary", "unknown ArUco dictionary \"" + out.marker_dictionary +
                                                          "\" (known: " + calib::marker_dictionary_names() + ")");
  out.min_markers = int(s.integer("min_markers", out.min_markers, 4, 100));
  out.max_rms_mm = s.number("max_rms_mm", out.max_rms_mm, 0.01, 100);
  out.max_loo_mm = s.number("max_loo_mm", out.max_loo_mm, 0.01, 100);
  out.touch_max_height_mm = s.number("touch_max_height_mm", out.touch_max_height_mm, 0.1, 100);
  s.reject_unknown();
}

}  // namespace rbx1::daemon
