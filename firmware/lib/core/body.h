// The body's sizes the core works with, computed from the vehicle's facts (protocol/vehicle.toml,
// generated into vehicle_gen.h): change the body there and these follow. Compile-time only.
#pragma once
#include <stdint.h>

#include "vehicle_gen.h"

namespace rovernav {
namespace core {

/// floor(sqrt(n)), for constants (a loop: C++14 constexpr).
constexpr uint32_t isqrt_floor(uint32_t n) {
  uint32_t r = 0;
  while ((r + 1) * (r + 1) <= n) ++r;
  return r;
}

enum : uint16_t {
  kBodyHalfWidthMm = kBodyWidthMm / 2,   // centre line to side
  // centre to a corner: what sweeps round the centre in a turn on the spot (129 mm for the seed's rover)
  kBodyHalfDiagonalMm = isqrt_floor(static_cast<uint32_t>(kBodyLengthMm) * kBodyLengthMm +
                                    static_cast<uint32_t>(kBodyWidthMm) * kBodyWidthMm) / 2,
};

}  // namespace core
}  // namespace rovernav
