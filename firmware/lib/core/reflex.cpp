// The forward reflex: between sweeps, while driving, the sonar pings ahead and to the sides;
// an echo on the rover's way within its stopping distance stops it in that step.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"
#include "progmem.h"

namespace rovernav {
namespace core {

float Rover::reflex_range_mm() const {
  const Params& p = params_;
  const float stop_mm = drive_speed_mm_s() * static_cast<float>(p.reflex_ping_ms() + kReflexLatencyMs) / 1000.0f;
  return stop_mm + p.reflex_margin_mm();
}

// The forward reflex: while driving, the sonar (pointing ahead between sweeps) pings every
// reflex_ping_ms; an echo on the path nearer than the stopping distance plus the margin stops
// the motors in that step, is reported, and a sweep follows (then the rover's detour or the
// host's new path). Returns whether it stopped the rover. An echo from beyond the waypoint
// being approached (by more than the robot's radius) is no threat to this leg: the goal in
// front of a wall is reached, not refused.
bool Rover::reflex(const SonarIn& in, uint32_t now, float l_mm, Outputs& out) {
  const Params& p = params_;
  const uint16_t period_ms = p.reflex_ping_ms();
  if (period_ms == 0) return false;
  // Ahead, right 15 and 30 degrees, ahead, left 15 and 30: at close range the 15-degree cone is
  // far narrower than the rover, and a corner beside the path would pass unseen straight ahead.
  static const int16_t kLookCdeg[kReflexLooks] ROVERNAV_PROGMEM = {0, 1500, 3000, 0, -1500, -3000};
  // A ping's result, or none in time (then it pings again): on to the next look either way.
  if (sonar_.reflex_waiting && (in.valid || static_cast<uint16_t>(now - sonar_.reflex_fired_ms) >= Sweep::kPingTimeoutMs)) {
    sonar_.reflex_waiting = false;
    const int16_t look = flash_read_i16(&kLookCdeg[sonar_.reflex_look_i]);
    // The index is always below kReflexLooks: a wrap, not a division (a library call on the Uno).
    sonar_.reflex_look_i = sonar_.reflex_look_i + 1u < kReflexLooks ? static_cast<uint8_t>(sonar_.reflex_look_i + 1) : 0;
    // None in time counts as no echo (the shell says "no echo" for a sensor that never answers
    // too): a look waiting on a silent sonar would hold the rover for good.
    const uint16_t r = in.valid ? in.range_mm : 0;
    if (r > 0 && reflex_on_path(look, r, l_mm)) {
      detour_.reflex_stopped();   // on a trusted path: the host's path is blocked after all
      sonar_.reflex_look = true;
      start_sweep();
      report_echo(look, r);
      send_event(EventKind::Reflex, r);
      out.left_pwm = out.right_pwm = 0;
      return true;
    }
    if (look == 0) sonar_.reflex_look = false;   // clear straight ahead
    // Off the way but near: remembered, for the turns to come (it will be beside the body).
    if (r > 0 && r <= kRememberPingMm) remember_echo(look, r);
  }
  sonar_.servo_cdeg = flash_read_i16(&kLookCdeg[sonar_.reflex_look_i]);
  if (!sonar_.reflex_waiting && static_cast<uint16_t>(static_cast<uint16_t>(now) - sonar_.reflex_fired_ms) >= period_ms) {
    out.fire_sonar = true;
    sonar_.reflex_waiting = true;
    sonar_.reflex_fired_ms = static_cast<uint16_t>(now);
  }
  // After a reflex stop the rover looks before it goes: no creeping up on what stopped it, a few
  // millimetres a ping.
  if (sonar_.reflex_look) {
    out.left_pwm = out.right_pwm = 0;
    return true;
  }
  return false;
}

// Whether an echo at bearing look_cdeg and range_mm may lie on the rover's way: nearer than the
// reflex range and no further to the side than the robot radius, wherever in the cone it came
// from, and not beyond the waypoint being approached (by more than the robot radius).
bool Rover::reflex_on_path(int16_t look_cdeg, uint16_t range_mm, float l_mm) const {
  const Params& p = params_;
  const float r = static_cast<float>(range_mm);
  const float look = fabsf(cdeg_to_rad(look_cdeg));
  // Each bound from where in the cone the echo would be nearest it: the stopping range along the
  // way from the cone's outer edge, the side from its inner edge. A side look sees a thing beside
  // the way last at its outer edge, then not again as the rover closes: measured on the axis, a box
  // corner 67 mm off the axis was 1 mm beyond the range at 30 degrees, and hit 120 mm on
  // (seed-small-obstacles, the link out at 20.6 s, seed 5744).
  const float half_cone = p.sonar_half_cone_rad();
  const float along_mm = r * cosf(look + half_cone);
  if (along_mm > reflex_range_mm()) return false;   // the stopping range, measured along the way
  const float nearest_side = look - half_cone;
  // (Below zero when the cone spans the axis: the side is no bound then.)
  if (r * sinf(nearest_side) > p.robot_radius_mm()) return false;
  return along_mm + p.sonar_offset_mm() <= l_mm + p.robot_radius_mm();
}

}  // namespace core
}  // namespace rovernav
