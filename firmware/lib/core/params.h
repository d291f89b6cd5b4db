// The rover's tunable parameters, set by CONFIG. Defaults and limits come from the protocol
// definition (param_limits() in messages_gen.h), so there is one list of them. Values are kept
// as the wire's integers, each in the least width its limits allow (kParamOffset: 86 bytes of the
// Uno's RAM where an int32 each took 140), and turned into working units where they are read: one
// small store instead of a field and a conversion per parameter keeps the Uno's flash free.
#pragma once
#include <stdint.h>

#include "heading_pid.h"
#include "messages_gen.h"
#include "noinline.h"

namespace rovernav {
namespace core {

enum class SetResult : uint8_t { Ok, UnknownParam, OutOfRange };

class Params {
 public:
  /// All parameters at their defaults.
  void reset();
  /// Sets parameter `id` to `value` after checking it against the definition's limits.
  SetResult set(uint8_t id, int32_t value);
  /// The value as its integer on the wire. Out of line: a read is a table look-up and a load of
  /// one, two or four bytes.
  ROVERNAV_NOINLINE int32_t raw(Param p) const;

  float kp() const { return unscaled<Param::PidKpX100>(); }         // PWM per degree
  float ki() const { return unscaled<Param::PidKiX100>(); }         // PWM per degree-second
  float kd() const { return unscaled<Param::PidKdX100>(); }         // PWM per degree/second
  float pid_out_max_pwm() const { return as_float(Param::PidOutMaxPwm); }
  PidGains pid_gains() const { return {kp(), ki(), kd(), pid_out_max_pwm()}; }
  float right_bias() const { return unscaled<Param::RightBiasPermille>(); }
  float drive_pwm() const { return as_float(Param::DrivePwm); }
  float cone_tol_mm() const { return as_float(Param::ConeTolMm); }
  float arrival_radius_mm() const { return as_float(Param::ArrivalRadiusMm); }
  float sweep_interval_mm() const { return as_float(Param::SweepIntervalMm); }
  uint16_t sweep_step_ms() const { return static_cast<uint16_t>(raw(Param::SweepStepMs)); }
  uint16_t sonar_report_mm() const { return static_cast<uint16_t>(raw(Param::SonarReportMm)); }
  uint32_t fix_timeout_ms() const { return static_cast<uint32_t>(raw(Param::FixTimeoutMs)); }
  uint32_t radio_timeout_ms() const { return static_cast<uint32_t>(raw(Param::RadioTimeoutMs)); }
  float dr_max_distance_mm() const { return as_float(Param::DrMaxDistanceMm); }
  float clearance_margin_mm() const { return as_float(Param::ClearanceMarginMm); }
  uint16_t status_period_ms() const { return static_cast<uint16_t>(raw(Param::StatusPeriodMs)); }   // at most 10,000 ([[params]])
  float rotate_done_deg() const { return hundredths(Param::RotateDoneCdeg); }
  uint32_t gyro_timeout_ms() const { return static_cast<uint32_t>(raw(Param::GyroTimeoutMs)); }
  int32_t gyro_max_rate_cdeg_s() const { return raw(Param::GyroMaxRateCdegS); }
  float speed_mm_s_per_pwm() const { return unscaled<Param::SpeedMmSPerPwmX1000>(); }
  int16_t motor_deadband_pwm() const { return static_cast<int16_t>(raw(Param::MotorDeadbandPwm)); }
  float wheel_mm_per_tick() const { return unscaled<Param::WheelMmPerTickX1000>(); }
  bool pose_law() const { return raw(Param::DriveMode) == static_cast<int32_t>(DriveMode::PoseLaw); }
  float pose_k_rho() const { return unscaled<Param::PoseKRhoX1000>(); }      // 1/s
  float pose_k_alpha() const { return unscaled<Param::PoseKAlphaX1000>(); }  // 1/s
  float pose_k_beta() const { return unscaled<Param::PoseKBetaX1000>(); }    // 1/s
  float pose_pwm_per_dps() const { return unscaled<Param::PosePwmPerDpsX1000>(); }
  uint16_t reflex_ping_ms() const { return static_cast<uint16_t>(raw(Param::ReflexPingMs)); }
  float reflex_margin_mm() const { return as_float(Param::ReflexMarginMm); }
  float sweep_before_turn_deg() const { return as_float(Param::SweepBeforeTurnDeg); }
  bool sweep_at_start() const { return raw(Param::SweepAtStart) != 0; }
  ROVERNAV_NOINLINE float robot_radius_mm() const { return as_float(Param::RobotRadiusMm); }
  ROVERNAV_NOINLINE float clearance_mm() const { return as_float(Param::RobotRadiusMm) + as_float(Param::SonarMarginMm); }
  float sonar_offset_mm() const { return as_float(Param::SonarOffsetMm); }
  ROVERNAV_NOINLINE float sonar_half_cone_rad() const { return scaled(Param::SonarConeCdeg, 0.5f * 0.01f * 0.017453292f); }

 private:
  // Out of line: a conversion (and a multiplication) written out at each of some thirty reads
  // costs the Uno more flash than the calls; so does a scale loaded at each (x100, per mille).
  ROVERNAV_NOINLINE float as_float(Param p) const { return static_cast<float>(raw(p)); }
  float scaled(Param p, float scale) const { return as_float(p) * scale; }
  ROVERNAV_NOINLINE float hundredths(Param p) const { return scaled(p, 0.01f); }
  ROVERNAV_NOINLINE float thousandths(Param p) const { return scaled(p, 0.001f); }
  /// A scaled parameter's working value: its integer over its scale, which the definition gives
  /// by its name (param_scale: _x100, _x1000, _permille), chosen at compile time.
  template <Param P>
  float unscaled() const {
    static_assert(param_scale(P) == 100 || param_scale(P) == 1000, "not a parameter scaled by 100 or 1000");
    return param_scale(P) == 100 ? hundredths(P) : thousandths(P);
  }
  void store(uint8_t id, int32_t value);
  uint8_t store_[kParamBytes];
};

}  // namespace core
}  // namespace rovernav
