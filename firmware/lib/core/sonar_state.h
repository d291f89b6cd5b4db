// The sonar: the sweep, the servo, and the forward reflex's pings.
#pragma once
#include <stdint.h>


#include "sweep.h"

namespace rovernav {
namespace core {

/// Written by mode_scan.cpp (the sweep) and reflex.cpp (the reflex's pings). The others through
/// the functions below: mode_rotate.cpp points the servo ahead (face_ahead) and has the reflex
/// look before the drive after a turn (look_from); link_out.cpp counts the echoes it reported
/// (count_echo). Left as it was: odometry.cpp adds the distance driven to sweep_distance_mm
/// itself, with float_ops.h's add_to(), as it does MotionState's turned_mm (see there).
struct SonarState {
  Sweep sweep;
  float sweep_distance_mm = 0.0f;
  float sweep_heading_rad = 0.0f;        ///< the heading the last sweep looked from
  int16_t servo_cdeg = 0;
  uint16_t scan_id = 0;
  uint8_t scan_echoes = 0;
  uint16_t reflex_fired_ms = 0;          ///< the forward reflex's last ping (ms, modulo 65,536)
  uint8_t reflex_look_i = 0;             ///< which way the reflex's next ping looks
  bool reflex_look : 1;                  ///< it stopped the rover: look (a clear ping) before driving
  bool reflex_waiting : 1;               ///< a ping's result is still to come

  void face_ahead() { servo_cdeg = 0; }
  /// The reflex looks (from look i of its cycle) before the rover drives on; a ping still out
  /// was aimed at another look.
  void look_from(uint8_t i) {
    reflex_look = true;
    reflex_waiting = false;
    reflex_look_i = i;
  }
  void count_echo() { ++scan_echoes; }
};

}  // namespace core
}  // namespace rovernav
