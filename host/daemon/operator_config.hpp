// operator_config.hpp - the [operator] table: jog bounds, background capture, workspace calibration bounds.
#pragma once
#include <string>

#include "config.hpp"

namespace rbx1::daemon {

struct OperatorConfig {
  double jog_max_deg = 10.0;   // largest joint change one jog request may ask for (dead-man bound)
  double jog_max_mm = 50.0;    // largest tool-point travel one Cartesian jog may ask for
  int background_frames = 8;   // frames averaged by `rbx1 background`
  // Workspace calibration (rbx1 calibrate-workspace).
  std::string marker_dictionary = "4X4_50";  // OpenCV ArUco dictionary of the printed markers
  int min_markers = 4;            // fewer recorded markers: refused
  double max_rms_mm = 1.0;        // a fit whose RMS residual is above this is refused
  double max_loo_mm = 2.0;        // ... or whose worst leave-one-out error is above this
  double touch_max_height_mm = 5.0;  // a recorded touch point must be this close to the table surface
};

void parse_operator_config(config::Section op, OperatorConfig& out);

}  // namespace rbx1::daemon
