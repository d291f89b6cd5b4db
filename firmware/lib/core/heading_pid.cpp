#include "heading_pid.h"

#include "float_ops.h"

namespace rovernav {
namespace core {

float HeadingPid::update(float error_deg, float rate_dps, float dt_s, const PidGains& g) {
  // Integrate small errors only (the seed's tuning: "the integral gain was increased for small
  // errors only"): a large turn must not wind the integral up and overshoot.
  if (positive(g.ki) && magnitude_below(error_deg, kIntegrateBelowDeg)) {
    integral_pwm_ = clamp(integral_pwm_ + g.ki * error_deg * dt_s, -g.out_max, g.out_max);
  } else {
    integral_pwm_ = 0.0f;
  }
  return clamp(g.kp * error_deg + integral_pwm_ - g.kd * rate_dps, -g.out_max, g.out_max);
}

}  // namespace core
}  // namespace rovernav
