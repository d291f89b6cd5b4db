// The detour: what the sonar saw near the body, Blocked and Planning, the rover's own way round.
#pragma once
#include <stdint.h>

#include "local_planner.h"
#include "mission_state.h"

namespace rovernav {
namespace core {

/// Written by detour.cpp. The others through the functions below: mode_drive.cpp goes on to the
/// next detour point (next_point) and, the last reached, ends the detour (drop), as the radio's
/// return does (failsafe.cpp); link_in.cpp takes the host's path (take_host_path) and HEARTBEAT's
/// word (hear_host), and forgets the echoes at START (forget); mode_scan.cpp starts a sweep
/// (sweep_starts; the planner's keep_near(), its own interface, keeps what lies beside the body);
/// reflex.cpp notes a stop (reflex_stopped); rover.cpp's enter() cuts a plan short (cancel_plan)
/// and, entering Blocked, starts its wait (blocked_at: one copy for detour.cpp's two ways in).
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

  void drop() { n = i = 0; }
  /// On to the next detour point; returns true when that was the last.
  bool next_point() { return ++i >= n; }
  void take_host_path() {
    drop();
    trusted_host = host_knows = false;
  }
  void hear_host(bool knows) { host_knows = knows; }
  void forget() { local.clear(); }
  void sweep_starts() { host_knows = false; }
  void reflex_stopped() {
    if (trusted_host) reflex_after_trust = true;
  }
  void blocked_at(uint32_t now_ms) { blocked_since_ms = now_ms; }
  void cancel_plan() {
    local.cancel();
    plan_ahead_dm = 0;
  }
};

}  // namespace core
}  // namespace rovernav
