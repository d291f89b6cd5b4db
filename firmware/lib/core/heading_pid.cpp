#include "heading_pid.h"

namespace rovernav {
namespace core {

namespace {
float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }
}  // namespace

float HeadingPid::update(float error_deg, float rate_dps, float dt_s, float kp, float ki, float kd, float out_max) {
  // Integrate small errors only (the seed's tuning: "the integral gain was increased for small
  // errors only"): a large turn must not wind the integral up and overshoot.
  if (ki > 0.0f && error_deg < kIntegrateBelowDeg && error_deg > -kIntegrateBelowDeg) {
    integral_ += error_deg * dt_s;
    const float limit = out_max / ki;
    integral_ = clampf(integral_, -limit, limit);
  } else {
    integral_ = 0.0f;
  }
  const float u = kp * error_deg + ki * integral_ - kd * rate_dps;
  return clampf(u, -out_max, out_max);
}

}  // namespace core
}  // namespace rovernav
