#include "angles.h"

#include <string.h>

#include "progmem.h"

namespace rovernav {
namespace core {

namespace {
// P's coefficients, highest power first, in flash: a loop over them takes less of it than the
// polynomial written out (every float constant is four loads at each use).
const float kAtanPoly[] ROVERNAV_PROGMEM = {0.02084507f, -0.08515627f, 0.18015924f, -0.33030477f, 0.99986631f};
uint32_t bits(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u;
}

}  // namespace

ROVERNAV_NOINLINE float wrap_rad(float a) {
  for (uint8_t i = 0; i < kWrapTurns; ++i) {
    if (a > kPi) {
      a -= 2.0f * kPi;
    } else if (a <= -kPi) {
      a += 2.0f * kPi;
    } else {
      break;
    }
  }
  return a;
}

// Signs and the comparison of magnitudes on the floats' bits (for non-negative floats the order
// of the bit patterns is the order of the values): no library call for them on the Uno.
ROVERNAV_NOINLINE float fast_atan2(float y, float x) {
  const uint32_t sign = 0x80000000u;
  const uint32_t bx = bits(x), by = bits(y);
  float ax = fabsf(x), ay = fabsf(y);
  const bool steep = (by & ~sign) > (bx & ~sign);
  if (steep) {
    const float swap = ax;
    ax = ay;
    ay = swap;
  }
  if ((bits(ax) & ~sign) == 0) return 0.0f;   // the origin
  const float t = ay / ax, s = t * t;
  float p = 0.0f;
  for (uint8_t i = 0; i < sizeof kAtanPoly / sizeof kAtanPoly[0]; ++i) p = p * s + flash_read_float(&kAtanPoly[i]);
  float a = t * p;
  if (steep) a = 0.5f * kPi - a;
  if (bx & sign) a = kPi - a;
  return (by & sign) ? -a : a;
}

}  // namespace core
}  // namespace rovernav
