// The detour: what the sonar saw near the body, Blocked and Planning, the rover's own way round.
#pragma once
#include <stdint.h>

#include "local_planner.h"
#include "mission_state.h"

namespace rovernav {
namespace core {

/// Written by detour.cpp. A new path (link_in.cpp), a waypoint's arrival (mode_drive.cpp) and
/// the radio's return (failsafe.cpp) end a detour (n = i = 0); link_in.cpp takes HEARTBEAT's word
/// (host_knows) and clears the memory at START; mode_scan.cpp keeps what lies beside the body at
/// a sweep's start; reflex.cpp notes a stop on a trusted path; rover.cpp's enter() cancels a plan.
struct DetourState {
  LocalPlanner local;                    ///< the last sweep's echoes, as obstacle disks
  Waypoint points[LocalPlanner::kMaxDetour] = {};
  uint8_t n = 0;
  uint8_t i = 0;                         ///< detour point being approached (== n: none)
  uint8_t plan_ahead_dm = 0;             ///< Planning: the detour rejoins the path this far on (100 mm)
  uint32_t blocked_since_ms = 0;
  bool awaiting_host : 1;                ///< Blocked after a sweep found the leg blocked (not: no detour found)
  bool trusted_host : 1;                 ///< the host sent no new path once this leg: it holds it clear
  bool reflex_after_trust : 1;           ///< ... and the reflex stopped the rover on it all the same
  bool host_knows : 1;                   ///< HEARTBEAT says the host heard the last sweep whole and holds our path
};

}  // namespace core
}  // namespace rovernav
