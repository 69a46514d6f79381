// clock_file.hpp - a simulated board's clock shared with its hosts through a mapped file (rbx1-avrsim --clock-file,
// rbx1-avrboard --clock-file).
#pragma once

#include <cstdint>
#include <string>

namespace rbx1::simpty {

// Creates `path` as 16 zero bytes (truncating it) and maps it shared: bytes 0-7 the simulated time (cycles, u64
// little-endian) the simulator keeps current, byte 8 the host's busy flag (rbx1-avrsim --hold-for-host). Returns
// the mapping, or nullptr with error set ("PATH: reason").
volatile uint8_t* map_clock_file(const std::string& path, std::string& error);

}  // namespace rbx1::simpty
