// Float helpers used in several places of the core, kept out of line. The Uno has no FPU:
// every float operation is a library call with its operands shuffled through registers, so a
// formula written out at each use costs flash that one shared copy does not. `inline` lets
// every file define them (the linker keeps one copy); ROVERNAV_NOINLINE keeps LTO from
// pasting them back in.
#pragma once
#include <math.h>

#include "noinline.h"

namespace rovernav {
namespace core {

/// Length of the vector (dx, dy): sqrt(dx^2 + dy^2), the plain formula (no overflow guard).
inline ROVERNAV_NOINLINE float length(float dx, float dy) { return sqrtf(dx * dx + dy * dy); }

/// sqrt(v), or 0 when v is not positive (or is NaN).
inline ROVERNAV_NOINLINE float sqrt_or_zero(float v) { return v > 0.0f ? sqrtf(v) : 0.0f; }

/// v clamped to [lo, hi].
inline ROVERNAV_NOINLINE float clamp(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

}  // namespace core
}  // namespace rovernav
