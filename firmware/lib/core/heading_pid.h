// The gyro PID that turns the rover on the spot and holds its heading while driving.
// Error in degrees; the derivative term uses the gyro's rate instead of differentiating the
// error, so a new target does not kick; the integral is clamped so it cannot wind up beyond
// what the output can use.
#pragma once

namespace rovernav {
namespace core {

/// The PID's gains (Params::pid_gains()): PWM per degree, per degree-second, per degree/second,
/// and the clamp on its output (PWM).
struct PidGains {
  float kp, ki, kd, out_max;
};

class HeadingPid {
 public:
  // Inline: the float's four zero stores are no larger than the call at its two sites (enter(),
  // reached_waypoint()); kept out of line it cost 8 bytes of flash with avr-gcc 7.3 and 5.4 alike.
  void reset() { integral_pwm_ = 0.0f; }
  /// error_deg: target minus heading; rate_dps: measured yaw rate (clockwise); dt_s: step.
  /// Returns the command in PWM, clamped to +-g.out_max.
  float update(float error_deg, float rate_dps, float dt_s, const PidGains& g);

 private:
  static constexpr float kIntegrateBelowDeg = 5.0f;
  // The integral term itself, ki times the degree-seconds (PWM): clamped to the output's range
  // with no division by ki each step.
  float integral_pwm_ = 0.0f;
};

}  // namespace core
}  // namespace rovernav
