// Blocked and Planning: what the sonar saw near the rover, kept as obstacle disks (LocalPlanner); whether
// the leg runs into it; waiting for the host's new path, or planning the rover's own detour, a
// slice a step, when the radio is down or the host's path proved blocked.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"
#include "sonar_geometry.h"

namespace rovernav {
namespace core {

void Rover::remember_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  // What the sonar saw, as the host's map marks it: the echo's arc (the obstacle may stand
  // anywhere across the cone at that range), as one disk round the point on the beam's axis
  // wide enough for the arc, plus the clearance the host plans with. Nothing is assumed behind it.
  const Params& p = params_;
  const float r = static_cast<float>(range_mm);
  const PointMm e = echo_point(odometry_.est.x_mm(), odometry_.est.y_mm(), odometry_.est.heading_rad(), cdeg_to_rad(bearing_cdeg), r,
                               p.sonar_offset_mm());
  Point c;
  c.x_mm = saturate_i16(e.x_mm);
  c.y_mm = saturate_i16(e.y_mm);
  const float half = p.sonar_half_cone_rad();   // tan as sin / cos: the image needs no tan of its own
  detour_.local.add(c, saturate_u16(p.clearance_mm() + r * sinf(half) / cosf(half)), here_mm());
}

Waypoint Rover::rejoin_point(float ahead_mm) const {
  // The point `ahead_mm` along the rest of the path: from the rover to mission_.path[mission_.wp], then on.
  Waypoint from = here_mm();
  float left = ahead_mm;
  for (uint8_t i = mission_.wp; i < mission_.path_len; ++i) {
    const Waypoint to = mission_.path[i];
    const float dx = to_float(to.x_mm - from.x_mm), dy = to_float(to.y_mm - from.y_mm);
    const float seg = length(dx, dy);
    if (seg >= left && positive(seg)) {
      const float f = left / seg;
      Waypoint w = {saturate_i16(from.x_mm + f * dx), saturate_i16(from.y_mm + f * dy)};
      return w;
    }
    left -= seg;
    from = to;
  }
  return mission_.path[mission_.path_len - 1];
}

// After a sweep: does the leg run into what the sonar saw, by the full clearance the host plans
// with? With the radio up the host, whose map knows more, replans after the sweep: the rover holds
// still and waits for its path, or for its word that it heard this sweep whole and keeps the path
// the rover holds (HEARTBEAT's scan_heard and path_id, detour_.host_knows); with the radio down, it plans
// its own detour after that wait (mode_blocked). It plans at once on a detour of its own, or when
// its forward reflex stopped it on a path it trusted all the same (a host that cannot replan). On a
// detour of its own, a sweep that finds the next detour point blocked plans the detour again from here.
void Rover::replan_locally() {
  detour_.awaiting_host = false;
  // Once the reflex has stopped the rover on the host's path, it does not take the host's word
  // again until a sweep finds the leg clear.
  const bool distrust = detour_.reflex_after_trust;
  detour_.reflex_after_trust = false;
  if (!mission_.active || detour_.local.echoes() == 0) return;
  if (!detour_.local.blocks(here_mm(), target(), 0, true)) return;
  detour_.reflex_after_trust = distrust;
  const bool on_own_detour = detour_.i < detour_.n;
  if (!detour_.reflex_after_trust && !on_own_detour) {
    detour_.awaiting_host = true;
    enter(RoverState::Blocked);
    return;
  }
  plan_detour();
}

// Blocked: returns true when the wait is over and the rover goes on along the leg.
bool Rover::mode_blocked(uint32_t now) {
  const uint32_t waited_ms = now - detour_.blocked_since_ms;
  if (failsafe_.radio_lost) {
    // The radio is down: after kBlockedWaitMs (a lossy radio's gaps are shorter; with the radio
    // up the rover sweeps again sooner), no path or word will come, and it plans its own way round.
    if (detour_.awaiting_host && waited_ms >= kBlockedWaitMs) {
      detour_.awaiting_host = false;
      plan_detour();
    }
    return false;
  }
  // Once the reflex has stopped it on the host's path and it found no way round, it does not
  // drive into what stopped it on the host's word again: it holds still until a new path comes.
  if (detour_.reflex_after_trust) return false;
  // On at once when the leg (a new path's, say) clears the echoes by the full clearance, or by
  // the sonar's placement margin when the host heard the sweep and keeps this path (an echo off a
  // face it already keeps clear of). Else, after the wait: with the host's word, on, trusting it
  // (its map knows more); without it (the sweep's reports lost on a lossy radio, or a host that
  // does not replan), the rover sweeps again: the readings said again, and the leg seen afresh.
  // It does not set off on its own way round while the radio is up: its sonar sees ahead only,
  // and the host's map holds what stands beside it.
  if (detour_.local.blocks(here_mm(), target(), detour_.host_knows ? static_cast<uint16_t>(params_.raw(Param::SonarMarginMm)) : 0, true)) {
    if (!detour_.host_knows) {
      if (waited_ms >= kUnheardWaitMs) start_sweep();
      return false;
    }
    if (waited_ms < kBlockedWaitMs) return false;
    detour_.trusted_host = true;
  }
  detour_.awaiting_host = false;
  enter(RoverState::Rotate);
  return true;
}

// The rover's own detour, planned over several steps (the wavefront a slice a step), while it
// holds still and keeps serving the link, STATUS and STOP. Rejoin points 0.9, 0.8, 0.7 and
// 0.6 m on along the path are tried in turn (the obstacle's depth is unknown).
void Rover::plan_detour() {
  step_.did(kWorkPlanned);
  // The path-staging buffer is the planner's scratch (unless a path is arriving: then the host's
  // new path will do, and the rover waits for it).
  static_assert(sizeof(link_.stage) >= LocalPlanner::kScratchBytes, "scratch fits the staging buffer");
  detour_.n = detour_.i = 0;
  if (link_.staging) {
    no_detour();
    return;
  }
  enter(RoverState::Planning);
  detour_.plan_ahead_dm = 10;
  next_detour_goal();
}

void Rover::next_detour_goal() {
  const Point a = here_mm();
  while (detour_.plan_ahead_dm > 6) {
    --detour_.plan_ahead_dm;
    const Waypoint goal = rejoin_point(100.0f * static_cast<float>(detour_.plan_ahead_dm));
    if (detour_.local.inside(goal)) continue;
    if (detour_.local.begin(a, goal, reinterpret_cast<uint8_t*>(link_.stage))) return;
  }
  detour_.plan_ahead_dm = 0;
  no_detour();
}

// One slice of the detour under way; called each step in Planning. A step that
// has done another heavy job (a FIX taken in, say) leaves it to the next.
void Rover::continue_detour() {
  if (step_.work & kWorkHeavy) {
    step_.defer();
    return;
  }
  // A frame to sign (a sweep's readings, STATUS) goes first: a plan runs for dozens of steps,
  // and frames held back all that while would fill the queue and be lost.
  if (link_.tx.wants_signing(link_.auth)) return;
  step_.did(kWorkPlanned);
  if (link_.staging) {   // the host's path is arriving: it will do
    no_detour();
    return;
  }
  uint8_t n = 0;
  const PlanStatus st = detour_.local.step(reinterpret_cast<uint8_t*>(link_.stage), detour_.points, n);
  if (st == PlanStatus::Running) return;
  if (st == PlanStatus::NoWay) {
    next_detour_goal();
    return;
  }
  detour_.n = n;
  detour_.i = 0;
  enter(RoverState::Rotate);
  send_event(EventKind::Replanned, n);
}

void Rover::no_detour() {
  detour_.n = detour_.i = 0;
  enter(RoverState::Blocked);   // a path from the host (or kBlockedWaitMs of it sending none) ends it
  send_event(EventKind::Replanned, 0);
}

}  // namespace core
}  // namespace rovernav
