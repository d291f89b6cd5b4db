// Rotate and BackOff: turning on the spot with the gyro PID, and backing straight out first
// when the last sweep saw something within reach of the rover's swinging corners.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"

namespace rovernav {
namespace core {

namespace {
// Rotation counts as done when also this slow (10 deg/s, in the gyro's mdps), so the rover does not
// coast past it.
const int32_t kRotateSettledMdps = 10000;
}  // namespace

// Rotate: the gyro PID turns the rover on the spot towards the target. Returns false once it
// faces it (then Drive, in this same step), true while it turns or has gone to back off first.
bool Rover::mode_rotate(float err, float l, float dt_s, Outputs& out) {
  const Params& p = params_;
  sonar_.face_ahead();   // the reflex's looks end: the sonar faces ahead for the next sweep or drive
  if (!motion_.rotate_checked) {
    // The check (a sine, a cosine and every echo) and a FIX's estimator update do not fit one
    // step: the turn begins a step later.
    if (step_.work & kWorkFix) {
      step_.defer();
      return true;
    }
    motion_.rotate_checked = true;
    // The host's word (motion_.back_out, from its PATH) counts as no room: its map keeps what the
    // rover's memory has let go.
    const bool back = fabsf(err) > static_cast<float>(kBackOffMinTurnDeg) && (motion_.back_out != 0 || !room_to_turn());
    if (!back) motion_.back_out = 0;   // a turn too small to swing the corners: the word is spent
    if (back || fabsf(err) > static_cast<float>(kTurnLookDeg)) {
      // Look before driving (after backing out too: no sweep looked from where the turn ends):
      // the reflex's pings right (or left) 15 and 30 degrees, then ahead, hold the wheels until
      // ahead is clear (Rover::reflex).
      sonar_.look_from(sign_bit(err) ? 4 : 1);   // |err| > 20: its sign bit is its sign
    }
    if (back) {
      send_event(EventKind::TurnRefused, saturate_u16(fabsf(err)));
      enter(RoverState::BackOff);
      return true;
    }
  }
  // The pose law steers while it drives: it only needs to face roughly the right way.
  // Rotate until well inside the cone the drive will hold: far from the waypoint the cone
  // atan(cone_tol / L) is narrower than rotate_done (0.6 degrees at 1.7 m), and a rotation
  // that stopped between the two would hand over to a drive that hands straight back.
  float done_deg = 0.5f * kPoseMaxErrorDeg;
  if (!p.pose_law()) {
    done_deg = p.rotate_done_deg();
    const float half_cone = 0.5f * cone_deg(l);
    if (half_cone < done_deg) done_deg = half_cone;
  }
  // done_deg is neither negative nor NaN (a NaN half cone is not taken): |err| <= done_deg on the bits.
  if (magnitude_at_most(err, done_deg) && failsafe_.rate_mdps < kRotateSettledMdps && failsafe_.rate_mdps > -kRotateSettledMdps) {
    enter(RoverState::Drive);
    return false;
  }
  turn_on_spot(err, dt_s, out);
  return true;
}

// The gyro PID's turn on the spot towards an error of err degrees.
void Rover::turn_on_spot(float err, float dt_s, Outputs& out) {
  motion_.track_is_segment = false;
  motion_.turned_mm = 0.0f;   // where it last turned: backing out retraces the drive since
  const float out_max = params_.pid_out_max_pwm();
  float u = heading_command(err, dt_s);
  // Lift the command over the motors' dead band, or small errors never close.
  if (magnitude_above(u, 0.5f)) {
    float lifted = fabsf(u) + to_float(params_.motor_deadband_pwm());
    if (!(lifted < out_max)) lifted = out_max;
    u = sign_bit(u) ? -lifted : lifted;   // |u| > 0.5: neither zero nor NaN, its sign bit is its sign
  }
  set_wheels(0.0f, u, false, out);
}

// Whether the last sweep saw nothing within reach of the corners as the rover turns on the spot:
// no echo within kSwingMm of the centre, and none abeam whose face may run back alongside the
// body (the sweep looks from the sonar, 100 mm ahead: it never sees the face beside the rear
// half, which a turn either way swings a corner into).
bool Rover::room_to_turn() const {
  const Point c = here_mm();
  const uint16_t clear = saturate_u16(params_.clearance_mm());
  if (detour_.local.within(c, clear, kSwingMm, kCornerReachMm)) return false;
  int16_t fx = 0, fy = 0;
  heading_q8(fx, fy);
  return !detour_.local.beside(c, fx, fy, clear);
}

// The heading's unit vector times 256 (x, y), for the planner's integer geometry.
ROVERNAV_NOINLINE void Rover::heading_q8(int16_t& fx_q8, int16_t& fy_q8) const {
  const float h = odometry_.est.heading_rad();
  fx_q8 = static_cast<int16_t>(256.0f * sinf(h));
  fy_q8 = static_cast<int16_t>(256.0f * cosf(h));
}

// Backing out: straight back, holding the heading, until its corners can swing clear of what the
// sweep saw, or for kBackOffMaxMm at most; then the turn it put off. On its own check it backs
// over the ground it drove: first what it drove since its last turn on the spot, back to where it
// turned. If that drive was its track (the way it last drove a while), the ground beyond is
// ground it never drove: it stops there and turns (backing on past it backed a fleet's rover into
// a box's corner behind it, fleet seeds 2 and 3). If it had turned off its track there, it turns
// back onto the track (its corners sweep what they swept turning off it) and backs along it
// (turning back where it stood, off that spot, turned a corner into a box: seed 1's arena 119).
// A rover that has driven no track since it was switched on knows no ground: it backs straight
// out, blind. On the host's word (PATH back_out) it backs straight out the whole way: the host
// asks only where its map has room straight behind the rover.
void Rover::back_off(float dt_s, Outputs& out) {
  const Params& p = params_;
  const bool told = motion_.back_out != 0;
  if (!told && motion_.track_known && motion_.back_off_mm >= motion_.turned_mm) {
    const bool retraced = motion_.track_is_segment;
    const float off = rad_to_deg(wrap_rad(motion_.track_rad - odometry_.est.heading_rad()));
    if (!retraced && fabsf(off) > static_cast<float>(kBackOffTrackDeg)) {
      turn_on_spot(off, dt_s, out);
      return;
    }
    if (retraced) motion_.back_off_mm = static_cast<float>(kBackOffMaxMm);   // where it turned onto its track: no further
  }
  add_to(motion_.back_off_mm, drive_speed_mm_s() * dt_s);
  // Room is looked for in the steps without a FIX (as the turn's check above); backing out goes on.
  const bool fix_step = (step_.work & kWorkFix) != 0;
  if (fix_step) step_.defer();
  // Asked by the host, it backs out the whole way: its own check would find room at once.
  if ((!fix_step && !told && room_to_turn()) || at_least(motion_.back_off_mm, static_cast<float>(kBackOffMaxMm))) {
    motion_.back_out = 0;
    enter(RoverState::Rotate);
    motion_.rotate_checked = true;
    return;
  }
  const float u = heading_command(0.0f, dt_s);   // hold the heading: damp any turn
  set_wheels(-p.drive_pwm(), u, true, out);
}

}  // namespace core
}  // namespace rovernav
