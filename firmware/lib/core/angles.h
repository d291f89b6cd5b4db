// Angle helpers. Headings are clockwise from +y (up the camera image), the seed's gyro
// convention; the internal unit is the radian, the wire unit the centidegree.
#pragma once
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "noinline.h"

namespace rovernav {
namespace core {

static const float kPi = 3.14159265f;
static const float kRadPerDeg = kPi / 180.0f;
static const float kDegPerRad = 180.0f / kPi;

/// Wraps to (-pi, pi] an angle within kWrapTurns turns of it: the core wraps only sums and
/// differences of wrapped angles (two turns at most). A bounded loop, so a NaN (returned as it
/// is) or a huge value (returned less kWrapTurns turns) cannot stall the rover; in range, it
/// costs two comparisons. The whole turns taken off by a multiplication and the integer part
/// cost 204 bytes more of flash on the Uno (gcc 5.4).
enum : uint8_t { kWrapTurns = 4 };
float wrap_rad(float a);

ROVERNAV_NOINLINE inline float cdeg_to_rad(int32_t cdeg) { return static_cast<float>(cdeg) * (kRadPerDeg / 100.0f); }

/// Out of line: kDegPerRad is four loads at each of its five uses.
ROVERNAV_NOINLINE inline float rad_to_deg(float rad) { return rad * kDegPerRad; }

/// To centidegrees in (-18000, 18000].
inline int16_t rad_to_cdeg(float rad) {
  const float c = rad_to_deg(wrap_rad(rad)) * 100.0f;
  // Rounded half away from zero: the half of c's sign (its bit, where a comparison with zero is
  // a library call on the Uno; -0 takes -0.5 where it took 0.5, and both truncate to 0).
  uint32_t c_bits;
  memcpy(&c_bits, &c, sizeof c_bits);
  const int32_t r = static_cast<int32_t>(c + ((c_bits & 0x80000000u) ? -0.5f : 0.5f));
  return static_cast<int16_t>(r <= -18000 ? 18000 : r);
}

/// atan2(y, x) in [-pi, pi], within 1.2e-5 rad (0.0007 degrees) of the exact value: atan on [0, 1]
/// as t * P(t^2), P of degree 4 (fitted here to the least largest error: test_angles.cpp checks
/// the bound), one division. On the Uno it costs about half of avr-libc's atan2 (176 us), which
/// the rover called two or three times a step. (0, 0) gives 0.
float fast_atan2(float y, float x);


}  // namespace core
}  // namespace rovernav
