// Motion: the heading PID, the wheels' commands, and backing out to make room for a turn.
#pragma once
#include <stdint.h>


#include "heading_pid.h"

namespace rovernav {
namespace core {

/// Written by mode_rotate.cpp and mode_drive.cpp. The others through the functions below:
/// rover.cpp's step() keeps the commands it gave (commanded), its enter() starts a rotation, a
/// back-off or a drive (rotation_starts, back_off_starts, drive_starts, and pid.reset(), the
/// PID's own interface), and its heading_command(), the modes' helper, runs the PID (pid.update);
/// odometry.cpp records the track (on_track); link_in.cpp takes the host's word to back out from
/// PATH (host_back_out). Left as it was: odometry.cpp adds the distance driven to turned_mm itself,
/// with float_ops.h's add_to() (one call every such sum shares). An inline function here would
/// need float_ops.h in this header, and that cost the 7.3 image 6 bytes.
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
  bool track_is_segment : 1;             ///< ... the heading of the drive since its last turn on the spot

  void commanded(int16_t left_pwm, int16_t right_pwm) {
    left_cmd = left_pwm;
    right_cmd = right_pwm;
  }
  void rotation_starts() { rotate_checked = false; }
  void back_off_starts() { back_off_mm = 0.0f; }
  void drive_starts(float distance_mm) { min_distance_mm = distance_mm; }
  void on_track(float heading_rad) {
    track_rad = heading_rad;
    track_known = true;
    track_is_segment = true;
  }
  /// PATH's back_out: a turn on the spot still to be checked is checked again.
  void host_back_out(uint8_t back) {
    back_out = back;
    if (back_out != 0) rotate_checked = false;
  }
};

}  // namespace core
}  // namespace rovernav
