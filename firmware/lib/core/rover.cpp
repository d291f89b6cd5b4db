#include "rover.h"

#include <math.h>

#include "angles.h"
#include "float_ops.h"
#include "progmem.h"

namespace rovernav {
namespace core {

namespace {

// Dead-reckoning noise. The speed model's error is systematic, so its variance grows with the
// distance driven (a 3 % scale error is 30 mm after a metre: 1 mm^2 per mm); encoders are
// better. The gyro's variance grows with time (bias left after calibration, about 0.05 deg/s
// over 10 s) and with the angle turned (scale error, 1 %).
const float kModelVarPerMm = 1.0f;
const float kEncoderVarPerMm = 0.1f;
const float kGyroVarPerS = (0.16f * kRadPerDeg) * (0.16f * kRadPerDeg);
const float kGyroScaleSd = 0.01f;
// Largest step we integrate; a longer gap (a stalled shell) is clamped, not trusted.
const uint32_t kMaxStepMs = 250;
// Rotation counts as done when also this slow (deg/s), so the rover does not coast past it.
const float kRotateSettledDps = 10.0f;

int16_t clamp_pwm(float v) {
  if (v > 255.0f) return 255;
  if (v < -255.0f) return -255;
  return static_cast<int16_t>(lroundf(v));
}

// PWM above the motor's dead band, signed: what actually moves a wheel.
ROVERNAV_NOINLINE float effective_pwm(int16_t pwm, int16_t deadband) {
  const int16_t mag = static_cast<int16_t>(pwm < 0 ? -pwm : pwm);
  if (mag <= deadband) return 0.0f;
  const float e = static_cast<float>(mag - deadband);
  return pwm < 0 ? -e : e;
}

uint16_t saturate_u16(float v) {
  if (!(v > 0.0f)) return 0;
  if (v > 65535.0f) return 65535;
  return static_cast<uint16_t>(lroundf(v));
}

int16_t saturate_i16(float v) {
  if (v > 32767.0f) return 32767;
  if (v < -32768.0f) return -32768;
  return static_cast<int16_t>(lroundf(v));
}

}  // namespace

void Rover::begin(uint32_t boot_id, uint16_t reset_cause) {
  // A Rover starts in its default state (it is a global on the Uno: no copy of ~800 bytes on
  // a 2 KB stack); begin() only sets what the default cannot know.
  params_.reset();
  boot_id_ = boot_id;
  reset_cause_ = reset_cause;
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
  if (detour_i_ < detour_n_ || blocked_) f |= StatusFlag::LocalReplan;
  return f;
}

// ---------------------------------------------------------------- the step

ROVERNAV_NOINLINE void Rover::step(const Inputs& in, Outputs& out) {
  const uint32_t now = in.now_ms;
  step_work_ = 0;
  float dt_s = 0.0f;
  if (have_time_) {
    const uint32_t gap_ms = now - last_ms_;
    dt_s = static_cast<float>(gap_ms < kMaxStepMs ? gap_ms : kMaxStepMs) / 1000.0f;
  }
  last_ms_ = now;
  if (!booted_) {
    booted_ = have_time_ = true;
    last_rx_ms_ = gyro_last_ms_ = last_status_ms_ = now;
    send_hello();
    send_event(EventKind::Boot, reset_cause_);
  }

  for (uint8_t i = 0; i < in.rx_len; ++i) {
    if (decoder_.push(in.rx[i])) {
      last_rx_ms_ = now;
      handle_frame(decoder_.frame(), now);
    }
  }
  update_gyro(in, now);
  dead_reckon(in, dt_s, now);
  watch_link(now);

  out.fire_sonar = false;
  run_state(in, dt_s, now, out);
  left_cmd_ = out.left_pwm;
  right_cmd_ = out.right_pwm;
  out.servo_cdeg = servo_cdeg_;

  if (now - last_status_ms_ >= params_.status_period_ms()) {
    last_status_ms_ = now;
    send_status();
  }
  const uint8_t room = in.tx_room < kTxPerStep ? in.tx_room : static_cast<uint8_t>(kTxPerStep);
  out.tx_len = tx_.take(out.tx, room);
}

// ---------------------------------------------------------------- sensing

void Rover::update_gyro(const Inputs& in, uint32_t now) {
  if (in.gyro_valid) {
    const int32_t rate_cdeg_s = in.gyro_rate_mdps / 10;
    const int32_t mag = rate_cdeg_s < 0 ? -rate_cdeg_s : rate_cdeg_s;
    if (mag > params_.gyro_max_rate_cdeg_s()) {
      gyro_good_run_ = false;
      if (fault_ == FaultCode::None) raise_fault(FaultCode::GyroImplausible);
      return;
    }
    gyro_last_ms_ = now;
    rate_dps_ = static_cast<float>(in.gyro_rate_mdps) / 1000.0f;
    if (!gyro_good_run_) {
      gyro_good_run_ = true;
      gyro_good_since_ms_ = now;
    }
    if (fault_ != FaultCode::None && now - gyro_good_since_ms_ >= kGyroRecoverMs) {
      const FaultCode cleared = fault_;
      fault_ = FaultCode::None;
      send_event(EventKind::FaultCleared, static_cast<uint16_t>(cleared));
      enter(RoverState::Idle);
    }
    return;
  }
  if (now - gyro_last_ms_ > params_.gyro_timeout_ms()) {
    gyro_good_run_ = false;
    rate_dps_ = 0.0f;
    if (fault_ == FaultCode::None) raise_fault(FaultCode::GyroSilent);
  }
}

void Rover::dead_reckon(const Inputs& in, float dt_s, uint32_t now) {
  if (dt_s <= 0.0f) return;
  float d_mm = 0.0f;
  float var_d = 0.0f;
  const float mm_per_tick = params_.wheel_mm_per_tick();
  if (in.wheels_valid && mm_per_tick > 0.0f) {
    d_mm = 0.5f * static_cast<float>(in.left_ticks + in.right_ticks) * mm_per_tick;
    var_d = kEncoderVarPerMm * fabsf(d_mm);
  } else {
    const int16_t deadband = params_.motor_deadband_pwm();
    const float pwm = 0.5f * (effective_pwm(left_cmd_, deadband) + effective_pwm(right_cmd_, deadband));
    d_mm = speed_scale_ * params_.speed_mm_s_per_pwm() * pwm * dt_s;
    var_d = kModelVarPerMm * fabsf(d_mm);
  }
  const float dth = fault_ == FaultCode::None ? rate_dps_ * kRadPerDeg * dt_s : 0.0f;
  const float var_th = kGyroVarPerS * dt_s + (kGyroScaleSd * dth) * (kGyroScaleSd * dth);
  est_.predict(d_mm, dth, var_d, var_th, now);
  const float ad = fabsf(d_mm);
  if (dead_reckoning_) dr_distance_mm_ += ad;
  if (state_ == RoverState::Drive) {
    sweep_distance_mm_ += ad;
    calib_model_mm_ += d_mm;
  }
}

// ---------------------------------------------------------------- link watchdog

void Rover::watch_link(uint32_t now) {
  const bool radio_now_lost = now - last_rx_ms_ > params_.radio_timeout_ms();
  if (radio_now_lost && !radio_lost_) {
    radio_lost_ = true;
    radio_lost_since_ms_ = now;
    send_event(EventKind::LinkLost, 0);
  } else if (!radio_now_lost && radio_lost_) {
    radio_lost_ = false;
    look_after_outage_ = mission_;   // what the sonar reported meanwhile was lost: look again
    send_event(EventKind::LinkBack, saturate_u16(static_cast<float>(now - radio_lost_since_ms_) / 100.0f));
  }
  if (had_fix_ && !dead_reckoning_ && now - last_fix_ms_ > params_.fix_timeout_ms()) {
    dead_reckoning_ = true;
    dr_distance_mm_ = 0.0f;
    if (!radio_lost_) send_event(EventKind::CameraLost, camera_);
  }
  // Safe stop: never drive on past what the estimate can vouch for.
  const bool moving = state_ == RoverState::Rotate || state_ == RoverState::Drive || state_ == RoverState::Scan ||
                      state_ == RoverState::BackOff;
  if (mission_ && moving && dead_reckoning_) {
    const float u = uncertainty_2sd_mm();
    if (u >= 0.9f * params_.clearance_margin_mm() ||
        dr_distance_mm_ >= params_.dr_max_distance_mm()) {
      stop_sweep();
      enter(RoverState::Hold);
      send_event(EventKind::Hold, saturate_u16(u));
    }
  }
  if (state_ == RoverState::Hold && !dead_reckoning_ &&
      uncertainty_2sd_mm() < 0.5f * params_.clearance_margin_mm()) {
    wp_ = closest_target();
    enter(RoverState::Rotate);
    send_event(EventKind::Resumed, wp_);
  }
}

// ---------------------------------------------------------------- motion

ROVERNAV_NOINLINE void Rover::enter(RoverState s) {
  if (s != state_) pid_.reset();
  if (s == RoverState::Rotate && state_ != RoverState::Rotate) rotate_checked_ = false;
  if (s == RoverState::BackOff) back_off_mm_ = 0.0f;
  if (s == RoverState::Drive && state_ != RoverState::Drive) {
    calib_anchor_ = false;
    drive_since_ms_ = last_ms_;
    min_distance_mm_ = wp_ < path_len_ ? distance_to(target()) : 0.0f;
  }
  state_ = s;
  if (s == RoverState::Idle || s == RoverState::Arrived || s == RoverState::Fault) mission_ = false;
}

void Rover::raise_fault(FaultCode code) {
  fault_ = code;
  stop_sweep();
  enter(RoverState::Fault);
  send_event(EventKind::Fault, static_cast<uint16_t>(code));
}

void Rover::stop_sweep() {
  sweep_ = Sweep();
  servo_cdeg_ = 0;
}

Waypoint Rover::target() const { return detour_i_ < detour_n_ ? detour_[detour_i_] : path_[wp_]; }

float Rover::distance_to(Waypoint w) const {
  return length(static_cast<float>(w.x_mm) - est_.x_mm(), static_cast<float>(w.y_mm) - est_.y_mm());
}

float Rover::error_to_deg(Waypoint w) const {
  const float b = bearing_rad(est_.x_mm(), est_.y_mm(), w.x_mm, w.y_mm);
  return wrap_rad(b - est_.heading_rad()) * kDegPerRad;
}

float Rover::cone_deg(float distance_mm) const {
  return atan2f(params_.cone_tol_mm(), distance_mm) * kDegPerRad;
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
    const float ax = a.x_mm, ay = a.y_mm;
    // Differences of int16 are exact as floats: one conversion each instead of two and a subtraction.
    const float vx = static_cast<float>(b.x_mm - a.x_mm), vy = static_cast<float>(b.y_mm - a.y_mm);
    const float len2 = vx * vx + vy * vy;
    float t = len2 > 0.0f ? ((px - ax) * vx + (py - ay) * vy) / len2 : 0.0f;
    const bool before_start = t <= 0.0f;
    t = clamp(t, 0.0f, 1.0f);
    const float cx = ax + t * vx - px, cy = ay + t * vy - py;
    const float d2 = cx * cx + cy * cy;
    if (d2 < best) {
      best = d2;
      target = (i == 0 && before_start) ? 0 : static_cast<uint8_t>(i + 1);
    }
  }
  return target;
}

void Rover::reached_waypoint() {
  if (detour_i_ < detour_n_) {
    // A point of the rover's own detour: on to the next, or back onto the host's path.
    if (++detour_i_ >= detour_n_) {
      detour_n_ = detour_i_ = 0;
      wp_ = closest_target();
    }
    enter(RoverState::Rotate);
    return;
  }
  send_event(EventKind::WaypointReached, wp_);
  if (wp_ + 1 >= path_len_) {
    enter(RoverState::Arrived);
    send_event(EventKind::Arrived, wp_);
    return;
  }
  ++wp_;
  // Do not stop at a waypoint the next leg runs straight on from (the seed stopped at every one).
  const float l = distance_to(target());
  const float turn_deg = fabsf(error_to_deg(target()));
  if (state_ == RoverState::Drive && (params_.pose_law() || turn_deg <= cone_deg(l))) {
    min_distance_mm_ = l;
    return;
  }
  // A sharp turn on the spot swings the rover's corners wider than its sides: look round first,
  // unless it has only just done so (the sweep then hands over to the rotation).
  const float look_deg = params_.sweep_before_turn_deg();
  if (look_deg > 0.0f && turn_deg > look_deg && sweep_distance_mm_ >= static_cast<float>(kTurnLookAfterMm)) {
    start_sweep(last_ms_);
    return;
  }
  enter(RoverState::Rotate);
  pid_.reset();
}

float Rover::heading_command(float error_deg, float dt_s) {
  const Params& p = params_;
  return pid_.update(error_deg, rate_dps_, dt_s, p.kp(), p.ki(), p.kd(), p.pid_out_max_pwm());
}

void Rover::run_state(const Inputs& in, float dt_s, uint32_t now, Outputs& out) {
  out.left_pwm = out.right_pwm = 0;
  if (!mission_ || wp_ >= path_len_) return;
  const Params& p = params_;
  const float out_max = p.pid_out_max_pwm();

  if (state_ == RoverState::Scan) {
    int16_t servo = servo_cdeg_;
    bool fire = false;
    const Sweep::Echo echo = sweep_.step(now, in.sonar_valid, in.sonar_range_mm, servo, fire);
    servo_cdeg_ = servo;
    out.fire_sonar = fire;
    if (echo.valid) {
      if (echo.range_mm > 0 && echo.range_mm <= p.sonar_report_mm()) {
        report_echo(echo.bearing_cdeg, echo.range_mm);
      } else {
        report_clear(echo.bearing_cdeg);   // nothing within the report range: the host clears the cone
      }
    }
    if (!sweep_.running()) {
      send_event(EventKind::ScanDone, scan_echoes_);
      sweep_distance_mm_ = 0.0f;
      enter(RoverState::Rotate);
      replan_locally();
    }
    return;
  }
  if (plan_ahead_dm_ != 0) {   // planning its own detour, a slice a step: holding still
    continue_detour();
    return;
  }
  if (blocked_) {
    // Waiting for the host's new path (or no way round on the rover's grid). If none comes, the
    // host (whose map knows more) holds the path clear: the rover goes on, once trusting it.
    if (awaiting_host_ && radio_lost_) {
      awaiting_host_ = false;
      plan_detour();   // the radio went down while it waited: no path will come
      return;
    }
    if (radio_lost_ || now - blocked_since_ms_ < kBlockedWaitMs) return;
    blocked_ = awaiting_host_ = false;
    trusted_host_ = true;
  }

  if (state_ == RoverState::BackOff) {
    back_off(dt_s, out);
    return;
  }
  if (state_ != RoverState::Rotate && state_ != RoverState::Drive) return;
  if (look_after_outage_) {
    // The radio is back: the host's map missed the readings sent while it was down (and may
    // have sent a path that runs into them). A sweep, reported, before the rover moves on.
    look_after_outage_ = false;
    start_sweep(now);
    return;
  }
  float l = distance_to(target());
  if (l <= p.arrival_radius_mm()) {
    reached_waypoint();
    if (!mission_ || state_ == RoverState::Scan) return;
    l = distance_to(target());
  }
  const float err = error_to_deg(target());

  if (state_ == RoverState::Rotate) {
    servo_cdeg_ = 0;   // the reflex's looks end: the sonar faces ahead for the next sweep or drive
    if (!rotate_checked_) {
      rotate_checked_ = true;
      if (fabsf(err) > static_cast<float>(kBackOffMinTurnDeg) && !room_to_turn()) {
        enter(RoverState::BackOff);
        return;
      }
    }
    // The pose law steers while it drives: it only needs to face roughly the right way.
    // Rotate until well inside the cone the drive will hold: far from the waypoint the cone
    // atan(cone_tol / L) is narrower than rotate_done (0.6 degrees at 1.7 m), and a rotation
    // that stopped between the two would hand over to a drive that hands straight back.
    float done_deg = p.pose_law() ? 0.5f * kPoseMaxErrorDeg : p.rotate_done_deg();
    if (!p.pose_law()) {
      const float half_cone = 0.5f * cone_deg(l);
      if (half_cone < done_deg) done_deg = half_cone;
    }
    if (fabsf(err) <= done_deg && fabsf(rate_dps_) < kRotateSettledDps) {
      enter(RoverState::Drive);
    } else {
      float u = heading_command(err, dt_s);
      // Lift the command over the motors' dead band, or small errors never close.
      if (fabsf(u) > 0.5f) {
        float lifted = fabsf(u) + static_cast<float>(p.motor_deadband_pwm());
        if (!(lifted < out_max)) lifted = out_max;
        u = u > 0.0f ? lifted : -lifted;
      }
      out.left_pwm = clamp_pwm(u);
      out.right_pwm = clamp_pwm(-u);
      return;
    }
  }

  if (state_ == RoverState::Drive && reflex(in, now, l, out)) return;

  if (p.pose_law() && state_ == RoverState::Drive) {
    if (p.sweep_interval_mm() > 0.0f && sweep_distance_mm_ >= p.sweep_interval_mm()) {
      start_sweep(now);
      return;
    }
    // Too far off (the goal behind the rover): turn on the spot first, as the seed would.
    if (fabsf(err) > kPoseMaxErrorDeg) {
      enter(RoverState::Rotate);
      return;
    }
    pose_command(l, out);
    return;
  }

  // Drive: stop and re-rotate outside the cone, or once we are moving away from the waypoint.
  if (fabsf(err) > cone_deg(l) || l > min_distance_mm_ + static_cast<float>(kGrowMarginMm)) {
    enter(RoverState::Rotate);
    return;
  }
  if (p.sweep_interval_mm() > 0.0f && sweep_distance_mm_ >= p.sweep_interval_mm()) {
    start_sweep(now);
    return;
  }
  if (l < min_distance_mm_) min_distance_mm_ = l;
  const float u = heading_command(err, dt_s);
  const float base = p.drive_pwm();
  out.left_pwm = clamp_pwm(base + u);
  out.right_pwm = clamp_pwm(base - u * p.right_bias());
}

ROVERNAV_NOINLINE void Rover::send_reading(int16_t bearing_cdeg, uint16_t range_mm) {
  msg::Obstacle o;
  o.scan_id = scan_id_;
  o.bearing_cdeg = bearing_cdeg;
  o.range_mm = range_mm;
  o.x_mm = saturate_i16(est_.x_mm());
  o.y_mm = saturate_i16(est_.y_mm());
  o.heading_cdeg = rad_to_cdeg(est_.heading_rad());
  o.sd_mm = saturate_u16(est_.position_sd_mm());
  tx_.send(o);
}

void Rover::report_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  send_reading(bearing_cdeg, range_mm);
  ++scan_echoes_;
  remember_echo(bearing_cdeg, range_mm);
}

void Rover::report_clear(int16_t bearing_cdeg) { send_reading(bearing_cdeg, 0); }

float Rover::drive_speed_mm_s() const {
  const Params& p = params_;
  const float v_mm_s = p.speed_mm_s_per_pwm() * speed_scale_ * (p.drive_pwm() - static_cast<float>(p.motor_deadband_pwm()));
  return v_mm_s > 0.0f ? v_mm_s : 0.0f;
}

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
bool Rover::reflex(const Inputs& in, uint32_t now, float l_mm, Outputs& out) {
  const Params& p = params_;
  const uint16_t period_ms = p.reflex_ping_ms();
  if (period_ms == 0) return false;
  // Ahead, right 15 and 30 degrees, ahead, left 15 and 30: at close range the 15-degree cone is
  // far narrower than the rover, and a corner beside the path would pass unseen straight ahead.
  static const int16_t kLookCdeg[kReflexLooks] ROVERNAV_PROGMEM = {0, 1500, 3000, 0, -1500, -3000};
  if (reflex_waiting_ && in.sonar_valid) {
    reflex_waiting_ = false;
    const uint16_t r = in.sonar_range_mm;
    const int16_t look = flash_read_i16(&kLookCdeg[reflex_look_i_]);
    reflex_look_i_ = static_cast<uint8_t>((reflex_look_i_ + 1) % kReflexLooks);
    if (r > 0 && reflex_on_path(look, r, l_mm)) {
      if (trusted_host_) reflex_after_trust_ = true;   // the host's path is blocked after all
      reflex_look_ = true;
      start_sweep(now);
      report_echo(look, r);
      send_event(EventKind::Reflex, r);
      out.left_pwm = out.right_pwm = 0;
      return true;
    }
    if (look == 0) reflex_look_ = false;   // clear straight ahead
  } else if (reflex_waiting_ && static_cast<uint16_t>(now - reflex_fired_ms_) >= Sweep::kPingTimeoutMs) {
    reflex_waiting_ = false;   // no result came: ping again
    reflex_look_i_ = static_cast<uint8_t>((reflex_look_i_ + 1) % kReflexLooks);
  }
  servo_cdeg_ = flash_read_i16(&kLookCdeg[reflex_look_i_]);
  if (!reflex_waiting_ && static_cast<uint16_t>(static_cast<uint16_t>(now) - reflex_fired_ms_) >= period_ms) {
    out.fire_sonar = true;
    reflex_waiting_ = true;
    reflex_fired_ms_ = static_cast<uint16_t>(now);
  }
  // After a reflex stop the rover looks before it goes: no creeping up on what stopped it, a few
  // millimetres a ping.
  if (reflex_look_) {
    out.left_pwm = out.right_pwm = 0;
    return true;
  }
  return false;
}

// Whether an echo at bearing look_cdeg and range_mm may lie on the rover's way: nearer than the
// reflex range, no further to the side than the robot radius wherever in the cone it came
// from, and not beyond the waypoint being approached (by more than the robot radius).
bool Rover::reflex_on_path(int16_t look_cdeg, uint16_t range_mm, float l_mm) const {
  const Params& p = params_;
  const float r = static_cast<float>(range_mm);
  const float look = fabsf(cdeg_to_rad(look_cdeg));
  if (r * cosf(look) > reflex_range_mm()) return false;   // the stopping range, measured along the way
  const float nearest_side = look - p.sonar_half_cone_rad();
  const float lateral_mm = nearest_side > 0.0f ? r * sinf(nearest_side) : 0.0f;
  if (lateral_mm > p.robot_radius_mm()) return false;
  return r * cosf(look) + p.sonar_offset_mm() <= l_mm + p.robot_radius_mm();
}

// Whether the last sweep saw nothing within reach of the corners as the rover turns on the spot.
bool Rover::room_to_turn() const {
  const Point c = {saturate_i16(est_.x_mm()), saturate_i16(est_.y_mm())};
  return !local_.within(c, saturate_u16(params_.clearance_mm()), kSwingMm);
}

// Backing out: straight back, holding the heading, the way the rover came (the only ground it
// knows is clear behind it), until its corners can swing clear of what the sweep saw, or for
// kBackOffMaxMm at most; then the turn it put off.
void Rover::back_off(float dt_s, Outputs& out) {
  const Params& p = params_;
  back_off_mm_ += drive_speed_mm_s() * dt_s;
  if (room_to_turn() || back_off_mm_ >= static_cast<float>(kBackOffMaxMm)) {
    enter(RoverState::Rotate);
    rotate_checked_ = true;
    return;
  }
  const float u = heading_command(0.0f, dt_s);   // hold the heading: damp any turn
  out.left_pwm = clamp_pwm(-p.drive_pwm() + u);
  out.right_pwm = clamp_pwm(-p.drive_pwm() - u * p.right_bias());
}

void Rover::start_sweep(uint32_t now) {
  reflex_waiting_ = false;   // a ping still out belongs to the reflex, not to the sweep
  ++scan_id_;
  scan_echoes_ = 0;
  cancel_detour_plan();
  local_.clear();
  sweep_.start(now, servo_cdeg_, params_.sweep_step_ms());
  enter(RoverState::Scan);
}

// The moving-to-a-pose law (Russo 2024, eq. 2.3-2.6, with alpha the bearing from the rover to
// the goal): rho, alpha, beta in the usual counter-clockwise frame from our clockwise headings,
// v = K_rho rho, omega = K_alpha alpha + K_beta beta; v through the speed model to a forward
// command, omega to a wheel difference. The goal heading at a waypoint is its next leg's.
void Rover::pose_command(float rho_mm, Outputs& out) {
  const Params& p = params_;
  const Waypoint w = target();
  float goal_cw = est_.heading_rad();
  const bool in_detour = detour_i_ < detour_n_;
  if (!in_detour && wp_ + 1 < path_len_) {
    goal_cw = bearing_rad(w.x_mm, w.y_mm, path_[wp_ + 1].x_mm, path_[wp_ + 1].y_mm);
  } else if (!in_detour && wp_ > 0) {
    goal_cw = bearing_rad(path_[wp_ - 1].x_mm, path_[wp_ - 1].y_mm, w.x_mm, w.y_mm);
  } else {
    goal_cw = bearing_rad(est_.x_mm(), est_.y_mm(), w.x_mm, w.y_mm);
  }
  // Counter-clockwise from +x: theta = pi/2 - clockwise-from-+y.
  const float theta = 0.5f * kPi - est_.heading_rad();
  const float theta_goal = 0.5f * kPi - goal_cw;
  const float alpha = wrap_rad(atan2f(static_cast<float>(w.y_mm) - est_.y_mm(), static_cast<float>(w.x_mm) - est_.x_mm()) - theta);
  const float beta = wrap_rad(-alpha - theta + theta_goal);
  const float v_max = p.speed_mm_s_per_pwm() * speed_scale_ * (p.drive_pwm() - static_cast<float>(p.motor_deadband_pwm()));
  // Slow down for the last waypoint only: the others are passed through at speed.
  const bool last = !in_detour && wp_ + 1 >= path_len_;
  float v = last ? p.pose_k_rho() * rho_mm : v_max;
  if (v > v_max) v = v_max;
  const float omega_ccw = p.pose_k_alpha() * alpha + p.pose_k_beta() * beta;   // rad/s
  const float per_pwm = p.speed_mm_s_per_pwm() * speed_scale_;
  float base = per_pwm > 0.0f ? static_cast<float>(p.motor_deadband_pwm()) + v / per_pwm : 0.0f;
  const float floor_pwm = static_cast<float>(p.motor_deadband_pwm()) + kPoseMinAbovePwm;
  if (base < floor_pwm) base = floor_pwm;   // keep creeping in: below the dead band it would stall
  const float u = -omega_ccw * kDegPerRad * p.pose_pwm_per_dps();   // clockwise turn: left wheel faster
  out.left_pwm = clamp_pwm(base + u);
  out.right_pwm = clamp_pwm(base - u * p.right_bias());
}

// ---------------------------------------------------------------- local replanning

void Rover::remember_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  // What the sonar saw, as the host's map marks it: the echo's arc (the obstacle may stand
  // anywhere across the cone at that range), as one disk round the point on the beam's axis
  // wide enough for the arc, plus the clearance the host plans with. Nothing is assumed behind it.
  const Params& p = params_;
  const float h = est_.heading_rad();
  const float b = h + cdeg_to_rad(bearing_cdeg);
  const float r = static_cast<float>(range_mm);
  const float off = p.sonar_offset_mm();
  Point c;
  c.x_mm = saturate_i16(est_.x_mm() + off * sinf(h) + r * sinf(b));
  c.y_mm = saturate_i16(est_.y_mm() + off * cosf(h) + r * cosf(b));
  local_.add(c, saturate_u16(p.clearance_mm() + r * tanf(p.sonar_half_cone_rad())));
}

Waypoint Rover::rejoin_point(float ahead_mm) const {
  // The point `ahead_mm` along the rest of the path: from the rover to path_[wp_], then on.
  Waypoint from = {saturate_i16(est_.x_mm()), saturate_i16(est_.y_mm())};
  float left = ahead_mm;
  for (uint8_t i = wp_; i < path_len_; ++i) {
    const Waypoint to = path_[i];
    const float seg = length(static_cast<float>(to.x_mm - from.x_mm), static_cast<float>(to.y_mm - from.y_mm));
    if (seg >= left && seg > 0.0f) {
      const float f = left / seg;
      Waypoint w = {saturate_i16(from.x_mm + f * static_cast<float>(to.x_mm - from.x_mm)),
                    saturate_i16(from.y_mm + f * static_cast<float>(to.y_mm - from.y_mm))};
      return w;
    }
    left -= seg;
    from = to;
  }
  return path_[path_len_ - 1];
}

// After a sweep: does the leg run into what the sonar saw (by more than the sonar's placement
// margin: the host plans with the full clearance, and an echo off a face it already keeps clear of
// must not set the rover off on its own)? With the radio up the host, whose map knows more,
// replans after the sweep: the rover holds still and waits for its path. It plans its own
// detour when the radio is down, or when it trusted the host's path once this leg and its
// forward reflex stopped it on that path all the same (a host that cannot replan). On a detour
// of its own, a sweep that finds the next detour point blocked plans the detour again from here.
void Rover::replan_locally() {
  blocked_ = false;
  awaiting_host_ = false;
  if (!mission_ || local_.echoes() == 0) return;
  const Waypoint here = {saturate_i16(est_.x_mm()), saturate_i16(est_.y_mm())};
  const Waypoint next = target();
  const Point a = {here.x_mm, here.y_mm}, b = {next.x_mm, next.y_mm};
  if (!local_.blocks(a, b, static_cast<uint16_t>(params_.raw(Param::SonarMarginMm)))) return;
  const bool on_own_detour = detour_i_ < detour_n_;
  if (!radio_lost_ && !reflex_after_trust_ && !on_own_detour) {
    blocked_ = awaiting_host_ = true;
    blocked_since_ms_ = last_ms_;
    return;
  }
  plan_detour();
}

// The rover's own detour, planned over several steps (the wavefront a slice a step), while it
// holds still and keeps serving the link, STATUS and STOP. Rejoin points 0.9, 0.8, 0.7 and
// 0.6 m on along the path are tried in turn (the obstacle's depth is unknown).
void Rover::plan_detour() {
  step_work_ = static_cast<uint8_t>(step_work_ | kWorkPlanned);
  // The path-staging buffer is the planner's scratch (unless a path is arriving: then the host's
  // new path will do, and the rover waits for it).
  static_assert(sizeof(stage_) >= LocalPlanner::kScratchBytes, "scratch fits the staging buffer");
  detour_n_ = detour_i_ = 0;
  if (staging_) {
    no_detour();
    return;
  }
  plan_ahead_dm_ = 10;
  next_detour_goal();
}

void Rover::next_detour_goal() {
  const Point a = {saturate_i16(est_.x_mm()), saturate_i16(est_.y_mm())};
  while (plan_ahead_dm_ > 6) {
    --plan_ahead_dm_;
    const Waypoint goal = rejoin_point(100.0f * static_cast<float>(plan_ahead_dm_));
    if (local_.inside(goal)) continue;
    if (local_.begin(a, goal, reinterpret_cast<uint8_t*>(stage_))) return;
  }
  plan_ahead_dm_ = 0;
  no_detour();
}

// One slice of the detour under way; called each step while plan_ahead_dm_ != 0. A step that
// has taken in a FIX (the estimator's update is the other heavy job) leaves it to the next.
void Rover::continue_detour() {
  if (step_work_ & kWorkFix) return;
  step_work_ = static_cast<uint8_t>(step_work_ | kWorkPlanned);
  if (staging_) {   // the host's path is arriving: it will do
    cancel_detour_plan();
    no_detour();
    return;
  }
  uint8_t n = 0;
  const PlanStatus st = local_.step(detour_, n);
  if (st == PlanStatus::Running) return;
  if (st == PlanStatus::NoWay) {
    next_detour_goal();
    return;
  }
  plan_ahead_dm_ = 0;
  detour_n_ = n;
  detour_i_ = 0;
  send_event(EventKind::Replanned, n);
}

void Rover::cancel_detour_plan() {
  local_.cancel();
  plan_ahead_dm_ = 0;
}

void Rover::no_detour() {
  detour_n_ = detour_i_ = 0;
  blocked_ = true;   // stopped; a path from the host (or kBlockedWaitMs of it sending none) ends it
  blocked_since_ms_ = last_ms_;
  send_event(EventKind::Replanned, 0);
}

// ---------------------------------------------------------------- messages in

ROVERNAV_NOINLINE void Rover::handle_frame(const Frame& f, uint32_t now) {
  switch (f.msg_id) {
    case msg::Hello::kId: {
      msg::Hello m{};
      decode_message(f, m);
      if (m.role == static_cast<uint8_t>(Role::Host)) {
        schema_ok_ = m.schema_hash == kSchemaHash;
        send_hello();
      }
      break;
    }
    case msg::Heartbeat::kId: {
      msg::Heartbeat m{};
      decode_message(f, m);
      camera_ = m.camera;
      break;
    }
    case msg::Fix::kId: {
      msg::Fix m{};
      decode_message(f, m);
      on_fix(m, now);
      break;
    }
    case msg::Path::kId: {
      msg::Path m{};
      decode_message(f, m);
      on_path(m, f.seq);
      break;
    }
    case msg::Start::kId: {
      msg::Start m{};
      decode_message(f, m);
      on_start(m, f.seq);
      break;
    }
    case msg::Stop::kId: {
      msg::Stop m{};
      decode_message(f, m);
      on_stop(m, f.seq);
      break;
    }
    case msg::Config::kId: {
      msg::Config m{};
      decode_message(f, m);
      on_config(m, f.seq);
      break;
    }
    default:
      break;  // a rover-to-host message echoed back: valid, not for us
  }
}

void Rover::on_fix(const msg::Fix& m, uint32_t now) {
  step_work_ = static_cast<uint8_t>(step_work_ | kWorkFix);
  PoseFix fix;
  fix.x_mm = m.x_mm;
  fix.y_mm = m.y_mm;
  fix.heading_cdeg = m.heading_cdeg;
  fix.sd_mm = m.sd_mm;
  fix.taken_ms = now - m.age_ms - kLinkDelayMs;
  const FixResult r = est_.update(fix, now);
  if (r == FixResult::Rejected) return;
  last_fix_ms_ = now;
  had_fix_ = true;
  if (dead_reckoning_) {
    dead_reckoning_ = false;
    send_event(EventKind::CameraBack, saturate_u16(est_.last_innovation_mm()));
  }
  dr_distance_mm_ = 0.0f;
  // Calibrate the speed model on straight drives: fix-to-fix distance against the model's.
  if (state_ != RoverState::Drive || now - drive_since_ms_ < kCalibrateAfterMs || r != FixResult::Accepted) {
    calib_anchor_ = false;
    return;
  }
  if (!calib_anchor_) {
    calib_anchor_ = true;
    calib_x_mm_ = m.x_mm;
    calib_y_mm_ = m.y_mm;
    calib_model_mm_ = 0.0f;
    return;
  }
  if (calib_model_mm_ >= static_cast<float>(kCalibrateMinMm)) {
    const float fix_mm = length(static_cast<float>(m.x_mm - calib_x_mm_), static_cast<float>(m.y_mm - calib_y_mm_));
    const float ratio = fix_mm / calib_model_mm_;
    speed_scale_ = clamp(speed_scale_ * (1.0f + 0.3f * (ratio - 1.0f)), 0.3f, 3.0f);
    calib_x_mm_ = m.x_mm;
    calib_y_mm_ = m.y_mm;
    calib_model_mm_ = 0.0f;
  }
}

void Rover::on_path(const msg::Path& m, uint8_t seq) {
  const uint8_t id = msg::Path::kId;
  if (plan_ahead_dm_ != 0) {   // the staging buffer is the planner's scratch; the host's path will do
    cancel_detour_plan();
    no_detour();
  }
  // A repeat of the chunk just taken (its ACK was lost and the host sent it again): ACK again.
  if (m.path_id == stage_id_ && m.first_index == last_chunk_first_ &&
      (staging_ || (path_id_ == m.path_id && path_len_ == m.total))) {
    ack(id, seq);
    return;
  }
  if (m.total > kMaxWaypoints) return nack(id, seq, NackReason::TooManyWaypoints, kMaxWaypoints);
  if (m.total == 0) return nack(id, seq, NackReason::BadValue, 2);
  if (m.count == 0 || m.count > kWaypointsPerChunk || m.first_index + m.count > m.total)
    return nack(id, seq, NackReason::BadValue, 4);
  for (uint8_t i = 0; i < m.count; ++i) {
    if (m.x_mm[i] < 0 || m.y_mm[i] < 0) return nack(id, seq, NackReason::BadValue, static_cast<uint16_t>(m.first_index + i));
  }
  const bool continues = staging_ && m.path_id == stage_id_ && m.total == stage_total_;
  if (m.first_index == 0 && !continues) {
    staging_ = true;
    stage_id_ = m.path_id;
    stage_total_ = m.total;
    stage_count_ = 0;
  } else if (!continues || m.first_index != stage_count_) {
    return nack(id, seq, NackReason::OutOfOrder, continues ? stage_count_ : 0);
  }
  for (uint8_t i = 0; i < m.count; ++i) {
    stage_[m.first_index + i].x_mm = m.x_mm[i];
    stage_[m.first_index + i].y_mm = m.y_mm[i];
  }
  stage_count_ = static_cast<uint8_t>(stage_count_ + m.count);
  last_chunk_first_ = m.first_index;
  ack(id, seq);
  if (stage_count_ < stage_total_) return;

  // Complete: it replaces the path held, and a running mission follows it at once.
  staging_ = false;
  for (uint8_t i = 0; i < stage_total_; ++i) path_[i] = stage_[i];
  path_len_ = stage_total_;
  path_id_ = stage_id_;
  detour_n_ = detour_i_ = 0;  // the host's path replaces the rover's own detour
  blocked_ = awaiting_host_ = trusted_host_ = reflex_after_trust_ = false;
  send_event(EventKind::PathAccepted, path_id_);
  if (mission_ && est_.initialised()) {
    wp_ = closest_target();
    if (state_ == RoverState::Drive || state_ == RoverState::Rotate) enter(RoverState::Rotate);
  }
}

void Rover::on_start(const msg::Start& m, uint8_t seq) {
  const uint8_t id = msg::Start::kId;
  if (!schema_ok_) return nack(id, seq, NackReason::SchemaMismatch, 0);
  if (fault_ != FaultCode::None) return nack(id, seq, NackReason::Faulted, static_cast<uint16_t>(fault_));
  if (path_len_ == 0) return nack(id, seq, NackReason::NoPath, 0);
  if (m.path_id != path_id_) return nack(id, seq, NackReason::PathIdMismatch, path_id_);
  if (!est_.initialised()) return nack(id, seq, NackReason::NoFix, 0);
  ack(id, seq);
  if (mission_) return;  // already running this path
  mission_ = true;
  wp_ = closest_target();
  // sweep_distance_mm_ carries over: "every 0.3 m travelled" counts across missions too.
  // Look before the first turn: something beside the rover would be hit by its corners as it turns.
  if (params_.sweep_at_start()) {
    start_sweep(last_ms_);
  } else {
    enter(RoverState::Rotate);
  }
}

void Rover::on_stop(const msg::Stop& m, uint8_t seq) {
  ack(msg::Stop::kId, seq);
  stop_sweep();
  cancel_detour_plan();
  if (state_ != RoverState::Fault) enter(RoverState::Idle);
  mission_ = false;
  send_event(EventKind::Stopped, m.reason);
}

void Rover::on_config(const msg::Config& m, uint8_t seq) {
  switch (params_.set(m.param, m.value)) {
    case SetResult::Ok: return ack(msg::Config::kId, seq);
    case SetResult::UnknownParam: return nack(msg::Config::kId, seq, NackReason::UnknownParam, m.param);
    case SetResult::OutOfRange: return nack(msg::Config::kId, seq, NackReason::ParamOutOfRange, m.param);
  }
}

// ---------------------------------------------------------------- messages out

void Rover::ack(uint8_t msg_id, uint8_t seq) {
  msg::Ack a;
  a.msg_id = msg_id;
  a.seq = seq;
  tx_.send(a);
}

void Rover::nack(uint8_t msg_id, uint8_t seq, NackReason reason, uint16_t detail) {
  msg::Nack n;
  n.msg_id = msg_id;
  n.seq = seq;
  n.reason = static_cast<uint8_t>(reason);
  n.detail = detail;
  tx_.send(n);
}

void Rover::send_hello() {
  msg::Hello h;
  h.schema_hash = kSchemaHash;
  h.boot_id = boot_id_;
  h.firmware_version = kFirmwareVersion;
  h.role = static_cast<uint8_t>(Role::Rover);
  h.max_waypoints = kMaxWaypoints;
  tx_.send(h);
}

void Rover::send_event(EventKind kind, uint16_t arg) {
  msg::Event e;
  e.kind = static_cast<uint8_t>(kind);
  e.arg = arg;
  e.time_ms = last_ms_;
  e.x_mm = saturate_i16(est_.x_mm());
  e.y_mm = saturate_i16(est_.y_mm());
  tx_.send(e);
}

ROVERNAV_NOINLINE void Rover::send_status() {
  msg::Status s;
  s.time_ms = last_ms_;
  s.state = static_cast<uint8_t>(state_);
  s.flags = flags();
  s.fault = static_cast<uint8_t>(fault_);
  s.path_id = path_id_;
  s.waypoint_index = wp_;
  s.x_mm = saturate_i16(est_.x_mm());
  s.y_mm = saturate_i16(est_.y_mm());
  s.heading_cdeg = rad_to_cdeg(est_.heading_rad());
  const float sxx = est_.p(0), syy = est_.p(3);
  s.sd_x_mm = saturate_u16(sqrt_or_zero(sxx));
  s.sd_y_mm = saturate_u16(sqrt_or_zero(syy));
  const float denom = sqrt_or_zero(sxx * syy);
  s.corr_xy_permille = denom > 0.0f ? saturate_i16(1000.0f * est_.p(1) / denom) : 0;
  s.sd_heading_cdeg = saturate_u16(sqrt_or_zero(est_.p(5)) * kDegPerRad * 100.0f);
  s.dr_distance_mm = saturate_u16(dr_distance_mm_);
  s.fix_age_ms = had_fix_ ? saturate_u16(static_cast<float>(last_ms_ - last_fix_ms_)) : 65535;
  s.left_pwm = left_cmd_;
  s.right_pwm = right_cmd_;
  const FrameCounters& c = decoder_.counters();
  s.rx_ok = c.frames_ok;
  s.rx_bad_crc = c.bad_crc;
  s.rx_overlong = c.overlong;
  s.rx_unknown_id = c.unknown_id;
  s.rx_malformed = c.malformed;
  s.tx_dropped = tx_.dropped();
  tx_.send(s);
}

}  // namespace core
}  // namespace rovernav
