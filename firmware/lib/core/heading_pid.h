// The gyro PID that turns the rover on the spot and holds its heading while driving.
// Error in degrees; the derivative term uses the gyro's rate instead of differentiating the
// error, so a new target does not kick; the integral is clamped so it cannot wind up beyond
// what the output can use.
#pragma once

namespace rovernav {
namespace core {

class HeadingPid {
 public:
  void reset() { integral_ = 0.0f; }
  /// error_deg: target minus heading; rate_dps: measured yaw rate (clockwise); dt_s: step.
  /// Returns the command in PWM, clamped to +-out_max.
  float update(float error_deg, float rate_dps, float dt_s, float kp, float ki, float kd, float out_max);

 private:
  static constexpr float kIntegrateBelowDeg = 5.0f;
  float integral_ = 0.0f;  // degree-seconds
};

}  // namespace core
}  // namespace rovernav
