// The rover's step and its one mode (step_.state): what each step does, in which order, and the
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
// Each concern's state is one aggregate of RoverFields (rover.h), in a header of its own, written
// by the concern's file: step_ (StepState, this file), link_ (LinkState), mission_ (MissionState),
// failsafe_ (FailsafeState), odometry_ (OdometryState), motion_ (MotionState), sonar_
// (SonarState, mode_scan.cpp and reflex.cpp), detour_ (DetourState). Another file changes an
// aggregate through the small inline functions its header gives for it; each header names the
// writes left as they were, and why.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"

namespace rovernav {
namespace core {

namespace {
// Largest step we integrate; a longer gap (a stalled shell) is clamped, not trusted.
const uint32_t kMaxStepMs = 250;
}  // namespace

void Rover::begin(uint32_t boot_id, uint16_t reset_cause, const LinkSecrets* secrets) {
  // A Rover starts in its default state (it is a global on the Uno: no copy of ~800 bytes on
  // a 2 KB stack); begin() only sets what the default cannot know.
  params_.reset();
  odometry_.begin();
  link_.begin(boot_id, reset_cause);
  const bool keyed = secrets != nullptr && secrets->has_key;
  link_.auth.begin(keyed ? secrets->key : nullptr);
  if (secrets != nullptr) {
    link_.auth.resume(secrets->tx_counter, secrets->rx_counter);
    link_.set_fleet(secrets->fleet_id);   // 0..kMaxRovers (link_store, rover_abi check it)
  }
}

bool Rover::persist_due(Counter48& tx_counter, Counter48& rx_counter) { return link_.take_persist(tx_counter, rx_counter); }

uint8_t Rover::take_key_change() { return link_.take_key_change(); }

uint16_t Rover::flags() const {
  uint16_t f = 0;
  if (mission_.path_len > 0) f |= StatusFlag::PathLoaded;
  if (mission_.active) f |= StatusFlag::MissionActive;
  if (failsafe_.dead_reckoning || !failsafe_.had_fix) f |= StatusFlag::DeadReckoning;
  if (failsafe_.radio_lost) f |= StatusFlag::RadioLost;
  if (!failsafe_.radio_lost && (failsafe_.dead_reckoning || link_.camera != static_cast<uint8_t>(CameraState::Ok))) f |= StatusFlag::CameraLost;
  if (failsafe_.fault == FaultCode::GyroSilent || failsafe_.fault == FaultCode::GyroImplausible) f |= StatusFlag::GyroFault;
  if (link_.schema_ok) f |= StatusFlag::SchemaOk;
  if (detour_.i < detour_.n || step_.state == RoverState::Blocked || step_.state == RoverState::Planning) f |= StatusFlag::LocalReplan;
  return f;
}

// ---------------------------------------------------------------- the step

ROVERNAV_NOINLINE void Rover::step(const Inputs& in, Outputs& out) {
  const uint32_t now = in.now_ms;
  step_.work = step_.put_off ? static_cast<uint8_t>(kWorkReserved) : static_cast<uint8_t>(0);
  step_.put_off = false;
  float dt_s = 0.0f;
  if (step_.have_time) {
    const uint32_t gap_ms = now - step_.now_ms();
    dt_s = static_cast<float>(gap_ms < kMaxStepMs ? gap_ms : kMaxStepMs) / 1000.0f;
  }
  step_.last_ms = now;
  if (!step_.booted) {
    step_.booted = step_.have_time = true;
    failsafe_.start(now);
    link_.first_step(now);
    send_hello();
    send_event(EventKind::Boot, link_.reset_cause);
  }
  link_.watch_counters();

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
  if (step_.sonar_held) {
    sonar.valid = true;
    sonar.range_mm = step_.held_sonar_mm;
    step_.sonar_held = false;
  }
  if (sonar.valid && (step_.work & (kWorkFix | kWorkTag))) {
    step_.sonar_held = step_.put_off = true;
    step_.held_sonar_mm = sonar.range_mm;
    sonar.valid = false;
  }
  out.fire_sonar = false;
  run_state(sonar, dt_s, now, out);
  motion_.commanded(out.left_pwm, out.right_pwm);
  out.servo_cdeg = sonar_.servo_cdeg;

  if (static_cast<uint16_t>(static_cast<uint16_t>(now) - link_.last_status_ms) >= params_.status_period_ms()) {
    if (step_.work & (kWorkFix | kWorkOther | kWorkTag)) {
      step_.put_off = true;
    } else {
      link_.status_sent(now);
      if (!send_link_auth()) send_status();
    }
  }
  uint8_t room = in.tx_room < kTxPerStep ? in.tx_room : static_cast<uint8_t>(kTxPerStep);
  // A rover of a fleet speaks only when spoken to ([fleet]): whole frames, in the grant the host's
  // last frame (or the reset) opened, which the step that took it and those within kGrantMs of it
  // share, kGrantBytes at most.
  if (link_.fleet) room = link_.grant_room(room, static_cast<uint16_t>(now - failsafe_.last_rx_ms));
  // Frames are framed (signed) on their way out, and not in a step that took a FIX, a sonar
  // result or a planner slice: what that step said leaves a step later (TxQueue).
  out.tx = link_.tx.take(link_.auth, room, !(step_.work & (kWorkFix | kWorkOther | kWorkPlanned)), out.tx_len, link_.fleet);
  link_.grant_left = static_cast<uint8_t>(link_.grant_left - out.tx_len);   // a lone rover's is not read
}

// The mode's work this step. Motors are off unless the mode drives them.
void Rover::run_state(const SonarIn& in, float dt_s, uint32_t now, Outputs& out) {
  out.left_pwm = out.right_pwm = 0;
  if (mission_.pick_target) {
    // A new path, a detour's end, a start or a resume: the nearest leg's end, when this step has
    // time for it (the search is a dozen float operations a segment); until then, hold still.
    if (step_.work & kWorkHeavy) {
      step_.put_off = true;
      return;
    }
    step_.did(kWorkOther);
    mission_.aim_at(closest_target());
  }
  if (!mission_.active || mission_.wp >= mission_.path_len) return;
  switch (step_.state) {
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
  if (failsafe_.look_after_outage) {
    // The radio is back: the host's map missed the readings sent while it was down (and may
    // have sent a path that runs into them). A sweep, reported, before the rover moves on.
    failsafe_.outage_looked();
    start_sweep();
    return;
  }
  float err = 0.0f;
  float l = aim(target(), &err);
  if (l <= params_.arrival_radius_mm() && !reached_waypoint(l, err)) return;
  if (step_.state == RoverState::Rotate && mode_rotate(err, l, dt_s, out)) return;
  mode_drive(in, err, l, dt_s, now, out);
}

ROVERNAV_NOINLINE void Rover::enter(RoverState s) {
  if (s != step_.state) {   // a mode left for another
    motion_.pid.reset();
    if (step_.state == RoverState::Planning) detour_.cancel_plan();   // a plan cut short (a sweep, a STOP, a path from the host, a fault)
    if (s == RoverState::Rotate) motion_.rotation_starts();
    if (s == RoverState::Drive) {
      odometry_.drive_starts(step_.now_ms());
      motion_.drive_starts(mission_.wp < mission_.path_len ? aim(target()) : 0.0f);
    }
  }
  if (s == RoverState::BackOff) motion_.back_off_starts();
  if (s == RoverState::Blocked) detour_.blocked_at(step_.now_ms());   // mode_blocked's wait starts (again)
  step_.state = s;
  if (s == RoverState::Idle || s == RoverState::Arrived || s == RoverState::Fault) mission_.end();
}

// ---------------------------------------------------------------- helpers of every mode

/// The estimate's position, rounded to whole mm (one copy of the two conversions).
ROVERNAV_NOINLINE Point Rover::here_mm() const { return {saturate_i16(odometry_.est.x_mm()), saturate_i16(odometry_.est.y_mm())}; }

Waypoint Rover::target() const { return detour_.i < detour_.n ? detour_.points[detour_.i] : mission_.path[mission_.wp]; }

ROVERNAV_NOINLINE float Rover::aim(Waypoint w, float* err_deg) const {
  const float dx = to_float(w.x_mm) - odometry_.est.x_mm(), dy = to_float(w.y_mm) - odometry_.est.y_mm();
  if (err_deg != nullptr) *err_deg = rad_to_deg(wrap_rad(fast_atan2(dx, dy) - odometry_.est.heading_rad()));
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
  if (mission_.path_len <= 1) return 0;
  const float px = odometry_.est.x_mm(), py = odometry_.est.y_mm();
  float best = 1e30f;
  uint8_t target = 0;
  for (uint8_t i = 0; i + 1 < mission_.path_len; ++i) {
    const Waypoint a = mission_.path[i], b = mission_.path[i + 1];
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
  return motion_.pid.update(error_deg, static_cast<float>(failsafe_.rate_mdps) * 0.001f, dt_s, params_.pid_gains());
}

}  // namespace core
}  // namespace rovernav
