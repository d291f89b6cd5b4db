#include "heading_pid.h"

#include "float_ops.h"

namespace rovernav {
namespace core {

ROVERNAV_NOINLINE float HeadingPid::update(float error_deg, float rate_dps, float dt_s, float kp, float ki, float kd, float out_max) {
  // Integrate small errors only (the seed's tuning: "the integral gain was increased for small
  // errors only"): a large turn must not wind the integral up and overshoot.
  if (ki > 0.0f && fabsf(error_deg) < kIntegrateBelowDeg) {
    integral_ += error_deg * dt_s;
    const float limit = out_max / ki;
    integral_ = clamp(integral_, -limit, limit);
  } else {
    integral_ = 0.0f;
  }
  const float u = kp * error_deg + ki * integral_ - kd * rate_dps;
  return clamp(u, -out_max, out_max);
}

}  // namespace core
}  // namespace rovernav
