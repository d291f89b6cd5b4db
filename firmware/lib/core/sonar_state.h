// The sonar: the sweep, the servo, and the forward reflex's pings.
#pragma once
#include <stdint.h>

#include "sweep.h"

namespace rovernav {
namespace core {

/// Written by mode_scan.cpp (the sweep) and reflex.cpp (the reflex's pings). odometry.cpp adds
/// the distance driven since the last sweep; mode_rotate.cpp points the servo ahead and sets the
/// reflex's look after a turn; link_out.cpp counts the echoes it reported.
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
};

}  // namespace core
}  // namespace rovernav
