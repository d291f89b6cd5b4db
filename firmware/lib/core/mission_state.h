// The mission: the host's path and the rover's place along it.
#pragma once
#include <stdint.h>

#include "local_planner.h"
#include "messages_gen.h"

namespace rovernav {
namespace core {

// A waypoint is a point of the plane in mm: the host's, or one of the rover's own detour.
using Waypoint = Point;

/// Written by link_in.cpp (PATH replaces the path, START and STOP begin and end the mission).
/// The others move along it through the functions below: rover.cpp chooses the nearest leg's
/// end (aim_at) and its enter() ends the mission in Idle, Arrived and Fault (end);
/// mode_drive.cpp goes on to the next waypoint (advance) or, a detour done, back to the nearest
/// leg (pick_again), as failsafe.cpp does on resuming (pick_again, pick_if_active).
struct MissionState {
  Waypoint path[kMaxWaypoints] = {};
  uint8_t path_len = 0;
  uint16_t path_id = 0;
  uint8_t wp = 0;                        ///< the waypoint being approached
  bool active : 1;                       ///< a mission runs (START taken, not yet ended)
  bool pick_target : 1;                  ///< wp is to be chosen afresh (closest_target) when the step has time

  void end() { active = false; }
  void advance() { ++wp; }
  void aim_at(uint8_t i) {
    pick_target = false;
    wp = i;
  }
  void pick_again() { pick_target = true; }
  /// The nearest leg's end is chosen again if a mission runs (and not else); returns whether one runs.
  bool pick_if_active() { return pick_target = active; }
};

}  // namespace core
}  // namespace rovernav
