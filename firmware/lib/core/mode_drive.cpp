// Drive: from waypoint to waypoint without stopping where the next leg runs straight on (the
// seed stopped at every grid cell), by the tolerance cone or the moving-to-a-pose law.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"

namespace rovernav {
namespace core {

// Drive: towards the target holding the heading with the gyro PID inside the tolerance cone
// atan(cone_tol_mm / L) (or steered by the pose law), the reflex watching ahead, a sweep every
// sweep_interval_mm; back to Rotate outside the cone or once moving away from the target.
void Rover::mode_drive(const SonarIn& in, float err, float l, float dt_s, uint32_t now, Outputs& out) {
  const Params& p = params_;
  if (reflex(in, now, l, out)) return;

  const float sweep_mm = p.sweep_interval_mm();
  const bool sweep_due = positive(sweep_mm) && sonar_.sweep_distance_mm >= sweep_mm;   // 0 disables sweeps
  if (p.pose_law()) {
    if (sweep_due) {
      start_sweep();
      return;
    }
    // Too far off (the goal behind the rover): turn on the spot first, as the seed would.
    if (magnitude_above(err, kPoseMaxErrorDeg)) {
      enter(RoverState::Rotate);
      return;
    }
    pose_command(l, err, out);
    return;
  }

  // Drive: stop and re-rotate outside the cone, or once we are moving away from the waypoint.
  if (fabsf(err) > cone_deg(l) || l > motion_.min_distance_mm + static_cast<float>(kGrowMarginMm)) {
    enter(RoverState::Rotate);
    return;
  }
  if (sweep_due) {
    start_sweep();
    return;
  }
  if (l < motion_.min_distance_mm) motion_.min_distance_mm = l;
  const float u = heading_command(err, dt_s);
  const float base = p.drive_pwm();
  set_wheels(base, u, true, out);
}

// The target was reached: on to the next. Returns false when this step is done with motion (the
// mission arrived, a sweep began, or the nearest leg is to be chosen first); otherwise l and err
// are the new target's distance and heading error (computed once: each is a square root or an
// arctangent, 100-150 us on the Uno).
bool Rover::reached_waypoint(float& l, float& err) {
  if (detour_.i < detour_.n) {
    // A point of the rover's own detour: on to the next, or back onto the host's path.
    if (detour_.next_point()) {
      detour_.drop();
      mission_.pick_again();
    }
    enter(RoverState::Rotate);
    if (mission_.pick_target) return false;
    l = aim(target(), &err);
    return true;
  }
  send_event(EventKind::WaypointReached, mission_.wp);
  if (mission_.wp + 1 >= mission_.path_len) {
    enter(RoverState::Arrived);
    send_event(EventKind::Arrived, mission_.wp);
    return false;
  }
  mission_.advance();
  // Do not stop at a waypoint the next leg runs straight on from (the seed stopped at every one).
  l = aim(target(), &err);
  const float turn_deg = fabsf(err);
  if (step_.state == RoverState::Drive && (params_.pose_law() || turn_deg <= cone_deg(l))) {
    motion_.min_distance_mm = l;
    return true;
  }
  // A sharp turn on the spot swings the rover's corners wider than its sides: look round first,
  // unless it has only just done so facing about this way (the sweep then hands over to the
  // rotation). A sweep that looked the other way saw nothing of what is round it now: a rover
  // that turned about after a sweep and met its next waypoint within 100 mm turned again into
  // a wall's end no beam had covered (arena 157).
  const float look_deg = params_.sweep_before_turn_deg();
  // sonar_.sweep_distance_mm is a sum of magnitudes, never negative: < 100 on its bits (false for a NaN,
  // as the comparison).
  const bool looked = magnitude_below(sonar_.sweep_distance_mm, static_cast<float>(kTurnLookAfterMm)) &&
                      magnitude_at_most(wrap_rad(odometry_.est.heading_rad() - sonar_.sweep_heading_rad), static_cast<float>(kTurnLookCoverDeg) * kRadPerDeg);
  if (positive(look_deg) && turn_deg > look_deg && !looked) {
    start_sweep();
    return false;
  }
  enter(RoverState::Rotate);
  motion_.pid.reset();
  return true;
}

// The moving-to-a-pose law (Russo 2024, eq. 2.3-2.6, with alpha the bearing from the rover to
// the goal): rho, alpha, beta in the usual counter-clockwise frame from our clockwise headings,
// v = K_rho rho, omega = K_alpha alpha + K_beta beta; v through the speed model to a forward
// command, omega to a wheel difference. The goal heading at a waypoint is its next leg's.
void Rover::pose_command(float rho_mm, float err_deg, Outputs& out) {
  const Params& p = params_;
  const Waypoint w = target();
  const bool in_detour = detour_.i < detour_.n;
  // In the counter-clockwise frame (theta = pi/2 - our clockwise heading): alpha, the goal's
  // bearing from the rover less theta, is minus the heading error; beta = -alpha - theta +
  // theta_goal = err + heading - goal heading. A detour's point, or a one-waypoint path, asks for
  // no heading but facing it: beta = 0.
  const float err_rad = err_deg * kRadPerDeg;
  const float alpha = -err_rad;
  float beta = 0.0f;
  if (!in_detour && mission_.path_len > 1) {
    const bool next = mission_.wp + 1 < mission_.path_len;
    const float goal_cw = bearing_rad(next ? w : mission_.path[mission_.wp - 1], next ? mission_.path[mission_.wp + 1] : w);
    beta = wrap_rad(err_rad + odometry_.est.heading_rad() - goal_cw);
  }
  const float v_max = drive_speed_mm_s();
  // Slow down for the last waypoint only: the others are passed through at speed.
  const bool last = !in_detour && mission_.wp + 1 >= mission_.path_len;
  float v = last ? p.pose_k_rho() * rho_mm : v_max;
  if (v > v_max) v = v_max;
  const float omega_ccw = p.pose_k_alpha() * alpha + p.pose_k_beta() * beta;   // rad/s
  const float per_pwm = mm_s_per_pwm();
  float base = positive(per_pwm) ? to_float(p.motor_deadband_pwm()) + v / per_pwm : 0.0f;
  const float floor_pwm = to_float(p.motor_deadband_pwm()) + kPoseMinAbovePwm;
  if (base < floor_pwm) base = floor_pwm;   // keep creeping in: below the dead band it would stall
  const float u = rad_to_deg(-omega_ccw) * p.pose_pwm_per_dps();   // clockwise turn: left wheel faster
  set_wheels(base, u, true, out);
}

}  // namespace core
}  // namespace rovernav
