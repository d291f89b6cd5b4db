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
/// The modes move along the path through their own writes of wp (rover.cpp chooses the nearest
/// leg's end, mode_drive.cpp goes on to the next), and rover.cpp's enter() ends the mission in
/// Idle, Arrived and Fault; pick_target is set by whoever makes the next target unknown (a new
/// path, a detour's end, a resume) and cleared by rover.cpp when it chooses.
struct MissionState {
  Waypoint path[kMaxWaypoints] = {};
  uint8_t path_len = 0;
  uint16_t path_id = 0;
  uint8_t wp = 0;                        ///< the waypoint being approached
  bool active : 1;                   ///< a mission runs (START taken, not yet ended)
  bool pick_target : 1;                  ///< wp is to be chosen afresh (closest_target) when the step has time
};

}  // namespace core
}  // namespace rovernav
