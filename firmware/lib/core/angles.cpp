#include "angles.h"

#include <string.h>

#include "float_ops.h"
#include "progmem.h"

namespace rovernav {
namespace core {

namespace {
// P's coefficients, highest power first, in flash: a loop over them takes less of it than the
// polynomial written out (every float constant is four loads at each use).
const float kAtanPoly[] ROVERNAV_PROGMEM = {0.02084507f, -0.08515627f, 0.18015924f, -0.33030477f, 0.99986631f};
float from_bits(uint32_t u) {
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
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
// of the bit patterns is the order of the values): no library call for them on the Uno. What
// the end needs of them is kept in one byte of flags, not in the floats they came from: held
// across the float calls, those took eight bytes of stack and their loads.
ROVERNAV_NOINLINE float fast_atan2(float y, float x) {
  enum : uint8_t { kSteep = 1, kXNegative = 2, kYNegative = 4 };
  const uint32_t sign = 0x80000000u;
  uint32_t bx = float_bits(x), by = float_bits(y);
  uint8_t flags = 0;
  if (bx & sign) flags |= kXNegative;
  if (by & sign) flags |= kYNegative;
  bx &= ~sign;
  by &= ~sign;
  if (by > bx) {
    flags |= kSteep;
    const uint32_t swap = bx;
    bx = by;
    by = swap;
  }
  if (bx == 0) return 0.0f;   // the origin
  const float t = from_bits(by) / from_bits(bx), s = t * t;
  float p = 0.0f;
  for (uint8_t i = 0; i < sizeof kAtanPoly / sizeof kAtanPoly[0]; ++i) p = p * s + flash_read_float(&kAtanPoly[i]);
  float a = t * p;
  if (flags & kSteep) a = 0.5f * kPi - a;
  if (flags & kXNegative) a = kPi - a;
  return (flags & kYNegative) ? -a : a;
}

}  // namespace core
}  // namespace rovernav
