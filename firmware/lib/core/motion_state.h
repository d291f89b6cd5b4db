// Motion: the heading PID, the wheels' commands, and backing out to make room for a turn.
#pragma once
#include <stdint.h>

#include "heading_pid.h"

namespace rovernav {
namespace core {

/// Written by mode_rotate.cpp and mode_drive.cpp. rover.cpp's step() keeps the commands it gave
/// (left_cmd, right_cmd) and enter() resets the PID and a rotation's or a drive's start;
/// odometry.cpp records the track driven (track_rad, track_known, turned_mm); link_in.cpp takes
/// the host's word to back out (back_out) from PATH.
struct MotionState {
  HeadingPid pid;
  float min_distance_mm = 0.0f;
  int16_t left_cmd = 0;
  int16_t right_cmd = 0;
  float back_off_mm = 0.0f;              ///< distance backed out so far
  float track_rad = 0.0f;                ///< the heading it last drove at (track_known): backing out goes along it
  float turned_mm = 0.0f;                ///< driven since it last turned on the spot: backing out retraces it first
  uint8_t back_out = 0;                  ///< the host's PATH: back out the whole way before the next turn on the spot
  bool rotate_checked : 1;               ///< this rotation's start was checked for room to swing
  bool track_known : 1;                  ///< track_rad holds a heading it drove at
};

}  // namespace core
}  // namespace rovernav
