// Dead reckoning between camera fixes: the wheels' encoders when fitted, else the speed model
// (PWM above the dead band times a calibrated scale), with the gyro's turn; and the speed
// model's calibration against the camera on straight drives.
#include "rover.h"

#include <math.h>
#include "angles.h"
#include "float_ops.h"
#include "noinline.h"

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

// PWM above the motor's dead band, signed: what actually moves a wheel.
ROVERNAV_NOINLINE float effective_pwm(int16_t pwm, int16_t deadband) {
  const int16_t mag = static_cast<int16_t>(pwm < 0 ? -pwm : pwm);
  if (mag <= deadband) return 0.0f;
  const float e = static_cast<float>(mag - deadband);
  return pwm < 0 ? -e : e;
}

}  // namespace

void Rover::dead_reckon(const Inputs& in, float dt_s, uint32_t now) {
  if (!positive(dt_s)) return;   // dt_s is never NaN: the same as dt_s <= 0, without the library call
  float d_mm = 0.0f;
  float var_d = 0.0f;
  const float mm_per_tick = kReadsWheelEncoders ? params_.wheel_mm_per_tick() : 0.0f;
  if (kReadsWheelEncoders && in.wheels_valid && positive(mm_per_tick)) {
    d_mm = 0.5f * static_cast<float>(in.left_ticks + in.right_ticks) * mm_per_tick;
    var_d = kEncoderVarPerMm * fabsf(d_mm);
  } else {
    const int16_t deadband = params_.motor_deadband_pwm();
    const float pwm = 0.5f * (effective_pwm(motion_.left_cmd, deadband) + effective_pwm(motion_.right_cmd, deadband));
    d_mm = mm_s_per_pwm() * pwm * dt_s;
    var_d = kModelVarPerMm * fabsf(d_mm);
  }
  const float dth = failsafe_.fault == FaultCode::None ? static_cast<float>(failsafe_.rate_mdps) * (kRadPerDeg / 1000.0f) * dt_s : 0.0f;
  const float var_th = kGyroVarPerS * dt_s + (kGyroScaleSd * dth) * (kGyroScaleSd * dth);
  odometry_.est.predict(d_mm, dth, var_d, var_th, now);
  const float ad = fabsf(d_mm);
  if (failsafe_.dead_reckoning) add_to(odometry_.dr_distance_mm, ad);
  if (step_.state == RoverState::Drive) {
    // The distance driven since the last sweep and since the last turn on the spot (SonarState,
    // MotionState): written here, through the one add_to() every such sum shares.
    add_to(sonar_.sweep_distance_mm, ad);
    add_to(motion_.turned_mm, ad);
    add_to(odometry_.calib_model_mm, d_mm);
    // The way it drives, once it has driven a while (a step of Drive between a turn and a sweep
    // is no track): backing out goes along it.
    if (now - odometry_.drive_since_ms >= kTrackAfterMs) {
      motion_.on_track(odometry_.est.heading_rad());
    }
  }
}

// The speed model's calibration on straight drives: the distance between two fixes against the
// model's distance over the same time, once the drive has settled (kCalibrateAfterMs) and the
// model has covered kCalibrateMinMm; the scale moves 30 % of the way to the ratio each time.
void Rover::calibrate_speed(const msg::Fix& m, uint32_t now, FixResult r) {
  if (step_.state != RoverState::Drive || now - odometry_.drive_since_ms < kCalibrateAfterMs || r != FixResult::Accepted) {
    odometry_.calib_anchor = false;
    return;
  }
  if (!odometry_.calib_anchor) {
    odometry_.calib_anchor = true;
    odometry_.calib_x_mm = m.x_mm;
    odometry_.calib_y_mm = m.y_mm;
    odometry_.calib_model_mm = 0.0f;
    return;
  }
  if (at_least(odometry_.calib_model_mm, static_cast<float>(kCalibrateMinMm))) {
    const float fix_mm = length(to_float(m.x_mm - odometry_.calib_x_mm), to_float(m.y_mm - odometry_.calib_y_mm));
    const float ratio = fix_mm / odometry_.calib_model_mm;
    odometry_.speed_scale = clamp(odometry_.speed_scale * (0.7f + 0.3f * ratio), 0.3f, 3.0f);   // 30 % of the way to the ratio
    odometry_.calib_x_mm = m.x_mm;
    odometry_.calib_y_mm = m.y_mm;
    odometry_.calib_model_mm = 0.0f;
  }
}

ROVERNAV_NOINLINE float Rover::mm_s_per_pwm() const { return params_.speed_mm_s_per_pwm() * odometry_.speed_scale; }

float Rover::drive_speed_mm_s() const {
  const Params& p = params_;
  const float v_mm_s = mm_s_per_pwm() * (p.drive_pwm() - to_float(p.motor_deadband_pwm()));
  return positive(v_mm_s) ? v_mm_s : 0.0f;
}

}  // namespace core
}  // namespace rovernav
