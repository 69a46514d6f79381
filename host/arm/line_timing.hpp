// line_timing.hpp - the durations of a straight line's segments: the line as one profile along its segments within
// every joint's speed and acceleration limits (the firmware's look-ahead model: per-segment limits of the dominant
// joint, the junction rule, backward and forward passes), stretched to the pace a joint move would keep.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "arm_config.hpp"

namespace rbx1::arm {

// The firmware's look-ahead over a stream of joint moves from rest to rest (firmware/README.md, Look-ahead), as
// the host predicts it: each segment's dominant rate limited by every joint's max_speed_steps_s and
// accel_steps_s2 (scaled to its share) and by its cruise cap (steps of the dominant joint per second), junctions
// by the firmware's rule. Returns the seconds the profile takes (without the firmware's per-step overheads).
double stream_seconds(const ArmConfig& cfg, const Steps& start, const std::vector<Steps>& targets,
                      const std::vector<double>& cap_steps_s);

// The junction a -> b -> c as the firmware's rule limits its dominant rate (steps/s): jump, a joint's velocity
// change within JUNCTION_LAG_STEPS of lag; curve, a joint's velocity change spread over the shorter segment within
// its ACCEL less the ramps' share; cruise, the slower segment's fastest rate within every joint's MAX_SPEED.
struct JunctionLimits {
  double jump = 0, curve = 0, cruise = 0;
};
JunctionLimits junction_limits(const ArmConfig& cfg, const Steps& a, const Steps& b, const Steps& c);

struct LineTiming {
  std::vector<uint16_t> duration_ms;  // MOVE.duration_ms of each segment (its cruise cap: n / duration)
  double fastest_s = 0;               // the stream at every joint's limits (stream_seconds, no cap below them)
  double pace_s = 0;                  // a joint move's rule: the largest joint travel at joint_speed_deg_s, min_move_ms
  double planned_s = 0;               // stream_seconds with the durations sent: max(fastest_s, pace_s), within rounding
};

// Times the segments start -> targets[0] -> ... of a line: as fast as the limits allow, but no faster than a joint
// move over the same joint travel would be timed (pace_s): then every cruise cap is scaled down by one factor, the
// ramps kept at the limits' acceleration (as the firmware stretches a joint move). false + error when a segment
// would take longer than MOVE.duration_ms allows (65535 ms).
bool time_line(const ArmConfig& cfg, const Steps& start, const std::vector<Steps>& targets, LineTiming& out,
               std::string& error);

}  // namespace rbx1::arm
