// The rover's step and its one mode (state_): what each step does, in which order, and the
// helpers every mode uses. The concerns live in their own files, as methods of the one class
// (the way ArduPilot's Rover keeps a file per concern; no virtual calls, no heap):
//   link_in.cpp    frames from the host: FIX, PATH assembly, START, STOP, CONFIG
//   link_out.cpp   frames to the host: HELLO, EVENT, STATUS, OBSTACLE, ACK/NACK
//   failsafe.cpp   the gyro's and the radio's watchdogs, faults, the safe stop (Hold)
//   odometry.cpp   dead reckoning and the speed model's calibration on straight drives
//   mode_scan.cpp  Scan: the sonar sweep and its reports
//   mode_rotate.cpp Rotate and BackOff: turning on the spot, backing out to make room for it
//   mode_drive.cpp Drive: the tolerance cone or the moving-to-a-pose law; waypoints reached
//   reflex.cpp     the forward reflex while driving
//   detour.cpp     Blocked and Planning: what a sweep found on the leg, the rover's own detour
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"

namespace rovernav {
namespace core {

namespace {
// Largest step we integrate; a longer gap (a stalled shell) is clamped, not trusted.
const uint32_t kMaxStepMs = 250;
static_assert(kSignPersistStep == 65536UL, "persist_due() compares the counters from byte 2 up");
}  // namespace

void Rover::begin(uint32_t boot_id, uint16_t reset_cause, const LinkSecrets* secrets) {
  // A Rover starts in its default state (it is a global on the Uno: no copy of ~800 bytes on
  // a 2 KB stack); begin() only sets what the default cannot know.
  params_.reset();
  speed_scale_ = 1.0f;
  boot_id_ = boot_id;
  reset_cause_ = reset_cause;
  const bool keyed = secrets != nullptr && secrets->has_key;
  auth_.begin(keyed ? secrets->key : nullptr);
  if (secrets != nullptr) auth_.resume(secrets->tx_counter, secrets->rx_counter);
}

bool Rover::persist_due(Counter48& tx_counter, Counter48& rx_counter) {
  if (!persist_due_) return false;
  persist_due_ = false;
  tx_counter = auth_.tx_last();
  rx_counter = auth_.rx_last();
  stored_tx_b2_ = tx_counter.b[2];
  for (uint8_t i = 0; i < 4; ++i) stored_rx_hi_[i] = rx_counter.b[2 + i];
  return true;
}

uint8_t Rover::take_key_change() {
  const uint8_t change = key_change_;
  key_change_ = 0;
  return change;
}

uint16_t Rover::flags() const {
  uint16_t f = 0;
  if (path_len_ > 0) f |= StatusFlag::PathLoaded;
  if (mission_) f |= StatusFlag::MissionActive;
  if (dead_reckoning_ || !had_fix_) f |= StatusFlag::DeadReckoning;
  if (radio_lost_) f |= StatusFlag::RadioLost;
  if (!radio_lost_ && (dead_reckoning_ || camera_ != static_cast<uint8_t>(CameraState::Ok))) f |= StatusFlag::CameraLost;
  if (fault_ == FaultCode::GyroSilent || fault_ == FaultCode::GyroImplausible) f |= StatusFlag::GyroFault;
  if (schema_ok_) f |= StatusFlag::SchemaOk;
  if (detour_i_ < detour_n_ || state_ == RoverState::Blocked || state_ == RoverState::Planning) f |= StatusFlag::LocalReplan;
  return f;
}

// ---------------------------------------------------------------- the step

ROVERNAV_NOINLINE void Rover::step(const Inputs& in, Outputs& out) {
  const uint32_t now = in.now_ms;
  step_work_ = put_off_ ? static_cast<uint8_t>(kWorkReserved) : static_cast<uint8_t>(0);
  put_off_ = false;
  float dt_s = 0.0f;
  if (have_time_) {
    const uint32_t gap_ms = now - last_ms_;
    dt_s = static_cast<float>(gap_ms < kMaxStepMs ? gap_ms : kMaxStepMs) / 1000.0f;
  }
  last_ms_ = now;
  if (!booted_) {
    booted_ = have_time_ = true;
    last_rx_ms_ = gyro_last_ms_ = boot_ms_ = now;
    last_status_ms_ = static_cast<uint16_t>(now);
    send_hello();
    send_event(EventKind::Boot, reset_cause_);
  }
  if (auth_.keyed()) {
    // At the first step (the counters resumed past the stored ones must be stored at once: a
    // second reset would resume from the same place), and when one has passed a multiple of
    // 65,536 since it was stored: the rover's own counts its frames (byte 2 changes), the
    // host's is its clock and may jump (any of bytes 2-5).
    bool moved = !persisted_once_ || auth_.tx_last().b[2] != stored_tx_b2_;
    for (uint8_t i = 0; i < 4; ++i) moved = moved || auth_.rx_last().b[2 + i] != stored_rx_hi_[i];
    if (moved) persisted_once_ = persist_due_ = true;
  }

  out.rx_used = take_frames(in, now);
  update_gyro(in, now);
  dead_reckon(in, dt_s, now);
  watch_link(now);

  // One heavy job a step, so that no step overruns half the Uno's 10 ms period: a FIX (the
  // estimator's update), a slice of the detour planner, the choice of the nearest leg, or a sonar
  // result with what follows from it (the echo's report and disk, a sweep's end and the check of
  // the leg). A sonar result that comes in a step that took a FIX waits for the next (the sweep
  // and the reflex see it 10 ms late; no new ping goes out meanwhile), a second FIX in one step is
  // dropped (the camera's next comes within 33 ms), and STATUS waits a step. A step that puts a
  // job off keeps the next for it: a FIX that comes then is dropped, so that fixes arriving every
  // step cannot starve the sweep, the planner or STATUS.
  SonarIn sonar = {in.sonar_valid, in.sonar_range_mm};
  if (sonar_held_) {
    sonar.valid = true;
    sonar.range_mm = held_sonar_mm_;
    sonar_held_ = false;
  }
  if (sonar.valid && (step_work_ & (kWorkFix | kWorkTag))) {
    sonar_held_ = put_off_ = true;
    held_sonar_mm_ = sonar.range_mm;
    sonar.valid = false;
  }
  out.fire_sonar = false;
  run_state(sonar, dt_s, now, out);
  left_cmd_ = out.left_pwm;
  right_cmd_ = out.right_pwm;
  out.servo_cdeg = servo_cdeg_;

  if (static_cast<uint16_t>(static_cast<uint16_t>(now) - last_status_ms_) >= params_.status_period_ms()) {
    if (step_work_ & (kWorkFix | kWorkOther | kWorkTag)) {
      put_off_ = true;
    } else {
      last_status_ms_ = static_cast<uint16_t>(now);
      if (!send_link_auth()) send_status();
    }
  }
  const uint8_t room = in.tx_room < kTxPerStep ? in.tx_room : static_cast<uint8_t>(kTxPerStep);
  // Frames are framed (signed) on their way out, and not in a step that took a FIX, a sonar
  // result or a planner slice: what that step said leaves a step later (TxQueue).
  out.tx = tx_.take(auth_, room, !(step_work_ & (kWorkFix | kWorkOther | kWorkPlanned)), out.tx_len);
}

// The mode's work this step. Motors are off unless the mode drives them.
void Rover::run_state(const SonarIn& in, float dt_s, uint32_t now, Outputs& out) {
  out.left_pwm = out.right_pwm = 0;
  if (pick_target_) {
    // A new path, a detour's end, a start or a resume: the nearest leg's end, when this step has
    // time for it (the search is a dozen float operations a segment); until then, hold still.
    if (step_work_ & kWorkHeavy) {
      put_off_ = true;
      return;
    }
    step_work_ = static_cast<uint8_t>(step_work_ | kWorkOther);
    pick_target_ = false;
    wp_ = closest_target();
  }
  if (!mission_ || wp_ >= path_len_) return;
  switch (state_) {
    case RoverState::Scan: return mode_scan(in, now, out);
    case RoverState::Planning: return continue_detour();
    case RoverState::BackOff: return back_off(dt_s, out);
    case RoverState::Blocked:
      if (!mode_blocked(now)) return;
      break;   // it waited long enough: on along the leg
    case RoverState::Rotate:
    case RoverState::Drive:
      break;
    default:
      return;
  }
  if (look_after_outage_) {
    // The radio is back: the host's map missed the readings sent while it was down (and may
    // have sent a path that runs into them). A sweep, reported, before the rover moves on.
    look_after_outage_ = false;
    start_sweep();
    return;
  }
  float err = 0.0f;
  float l = aim(target(), &err);
  if (l <= params_.arrival_radius_mm() && !reached_waypoint(l, err)) return;
  if (state_ == RoverState::Rotate && mode_rotate(err, l, dt_s, out)) return;
  mode_drive(in, err, l, dt_s, now, out);
}

ROVERNAV_NOINLINE void Rover::enter(RoverState s) {
  if (s != state_) pid_.reset();
  if (state_ == RoverState::Planning && s != RoverState::Planning) {
    local_.cancel();   // a plan cut short (a sweep, a STOP, a path from the host, a fault)
    plan_ahead_dm_ = 0;
  }
  if (s == RoverState::Rotate && state_ != RoverState::Rotate) rotate_checked_ = false;
  if (s == RoverState::BackOff) back_off_mm_ = 0.0f;
  if (s == RoverState::Drive && state_ != RoverState::Drive) {
    calib_anchor_ = false;
    drive_since_ms_ = last_ms_;
    min_distance_mm_ = wp_ < path_len_ ? aim(target()) : 0.0f;
  }
  state_ = s;
  if (s == RoverState::Idle || s == RoverState::Arrived || s == RoverState::Fault) mission_ = false;
}

// ---------------------------------------------------------------- helpers of every mode

/// The estimate's position, rounded to whole mm (one copy of the two conversions).
ROVERNAV_NOINLINE Point Rover::here_mm() const { return {saturate_i16(est_.x_mm()), saturate_i16(est_.y_mm())}; }

Waypoint Rover::target() const { return detour_i_ < detour_n_ ? detour_[detour_i_] : path_[wp_]; }

ROVERNAV_NOINLINE float Rover::aim(Waypoint w, float* err_deg) const {
  const float dx = to_float(w.x_mm) - est_.x_mm(), dy = to_float(w.y_mm) - est_.y_mm();
  if (err_deg != nullptr) *err_deg = rad_to_deg(wrap_rad(fast_atan2(dx, dy) - est_.heading_rad()));
  return length(dx, dy);
}

float bearing_rad(Point a, Point b) {
  // Differences of int16 are exact as floats: one conversion each.
  return fast_atan2(to_float(b.x_mm - a.x_mm), to_float(b.y_mm - a.y_mm));
}

float Rover::cone_deg(float distance_mm) const {
  return rad_to_deg(fast_atan2(params_.cone_tol_mm(), distance_mm));
}

uint8_t Rover::closest_target() const {
  // The end of the path segment nearest the rover, so that a path planned from where the
  // rover was a moment ago does not send it back; the start if the rover is before it.
  if (path_len_ <= 1) return 0;
  const float px = est_.x_mm(), py = est_.y_mm();
  float best = 1e30f;
  uint8_t target = 0;
  for (uint8_t i = 0; i + 1 < path_len_; ++i) {
    const Waypoint a = path_[i], b = path_[i + 1];
    // Differences of int16 are exact as floats: one conversion each instead of two and a subtraction.
    float t;
    const float d2 = segment_distance2(px - to_float(a.x_mm), py - to_float(a.y_mm),
                                       to_float(b.x_mm - a.x_mm), to_float(b.y_mm - a.y_mm), t);
    if (d2 < best) {
      best = d2;
      // t is no NaN here (with it, d2 is NaN too): t <= 0 is !positive(t), with no library call.
      target = (i == 0 && !positive(t)) ? 0 : static_cast<uint8_t>(i + 1);
    }
  }
  return target;
}

// The motor commands for a forward command `base` and a turn `u` (PWM; clockwise: left faster),
// the right side's turn scaled by right_bias (the stronger motor's correction) when `biased`.
ROVERNAV_NOINLINE void Rover::set_wheels(float base, float u, bool biased, Outputs& out) const {
  out.left_pwm = clamp_pwm(base + u);
  out.right_pwm = clamp_pwm(base - (biased ? u * params_.right_bias() : u));
}

float Rover::heading_command(float error_deg, float dt_s) {
  return pid_.update(error_deg, static_cast<float>(rate_mdps_) * 0.001f, dt_s, params_.pid_gains());
}

}  // namespace core
}  // namespace rovernav
