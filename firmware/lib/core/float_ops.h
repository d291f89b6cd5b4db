// Float helpers used in several places of the core, kept out of line. The Uno has no FPU:
// every float operation is a library call with its operands shuffled through registers, so a
// formula written out at each use costs flash that one shared copy does not. `inline` lets
// every file define them (the linker keeps one copy); ROVERNAV_NOINLINE keeps LTO from
// pasting them back in.
#pragma once
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "noinline.h"

namespace rovernav {
namespace core {

/// v as a float, for an int (16 bits on the Uno: a coordinate in mm, or the difference of two),
/// out of line: written out, each conversion is a sign extension to 32 bits and the library
/// call, a dozen bytes at each of some twenty uses.
inline ROVERNAV_NOINLINE float to_float(int v) { return static_cast<float>(v); }

/// The float's 32 bits. For two non-negative floats (or two negative ones, by magnitude) the
/// order of the bits is the order of the values: a comparison on them is a few instructions, where
/// the float comparison is a library call with its constant's four loads on the Uno.
inline uint32_t float_bits(float v) {
  uint32_t b;
  memcpy(&b, &v, sizeof b);
  return b;
}

enum : uint32_t {
  kFloatSignBit = 0x80000000u,
  kInfinityBits = 0x7F800000u,   ///< +infinity: every exponent bit, no mantissa; a NaN's magnitude lies above
};

/// v > 0 (false for a NaN), on the float's bits: its 32 bits less one lie below those of +infinity
/// for exactly the positive floats and +infinity. Out of line, and no library call: the
/// comparison written out is the zero's four loads and __gtsf2 at each of fourteen uses.
inline ROVERNAV_NOINLINE bool positive(float v) { return float_bits(v) - 1u < kInfinityBits; }

/// |v| > limit (limit >= 0; false for a NaN), on the bits: v's magnitude lies above limit's
/// and not above infinity's.
inline bool magnitude_above(float v, float limit) {
  const uint32_t magnitude = float_bits(v) & ~kFloatSignBit;
  return magnitude > float_bits(limit) && magnitude <= kInfinityBits;
}

/// |v| < limit (limit >= 0; false for a NaN), on the bits.
inline bool magnitude_below(float v, float limit) { return (float_bits(v) & ~kFloatSignBit) < float_bits(limit); }

/// v >= limit (limit > 0 and finite; false for a NaN), on the bits: v's lie in [limit's, +infinity's],
/// one unsigned range check (a negative float's bits lie above them all).
inline bool at_least(float v, float limit) {
  return float_bits(v) - float_bits(limit) <= kInfinityBits - float_bits(limit);
}

/// |v| <= limit (limit >= 0; false for a NaN), on the bits.
inline bool magnitude_at_most(float v, float limit) { return (float_bits(v) & ~kFloatSignBit) <= float_bits(limit); }

/// v's sign bit (set for -0 and the negative floats).
inline bool sign_bit(float v) { return (float_bits(v) & kFloatSignBit) != 0; }

/// v clamped to [lo, hi].
inline ROVERNAV_NOINLINE float clamp(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

/// acc += v, out of line: a float member's += written out is two four-byte moves and a call.
inline ROVERNAV_NOINLINE void add_to(float& acc, float v) { acc += v; }

/// dx^2 + dy^2.
inline ROVERNAV_NOINLINE float norm2(float dx, float dy) { return dx * dx + dy * dy; }

/// Length of the vector (dx, dy): sqrt(dx^2 + dy^2), the plain formula (no overflow guard).
inline ROVERNAV_NOINLINE float length(float dx, float dy) { return sqrtf(norm2(dx, dy)); }

/// The squared distance from point p to the segment from the origin to v (all relative to the
/// segment's start), and in t the nearest point's place along it before clamping to [0, 1]
/// (t <= 0: p lies before the start). One copy for the detour planner and the choice of leg.
inline ROVERNAV_NOINLINE float segment_distance2(float px, float py, float vx, float vy, float& t) {
  const float len2 = norm2(vx, vy);
  t = positive(len2) ? (px * vx + py * vy) / len2 : 0.0f;
  const float tc = clamp(t, 0.0f, 1.0f);
  return norm2(px - tc * vx, py - tc * vy);
}

/// sqrt(v), or 0 when v is not positive (or is NaN).
inline ROVERNAV_NOINLINE float sqrt_or_zero(float v) { return positive(v) ? sqrtf(v) : 0.0f; }


// The limits below are tested on the bits (magnitude_above(), sign_bit()): v > 255 is a v above
// 255 in magnitude without the sign bit, v < -255 one with it; a NaN is neither (as with the float
// comparisons) and goes to lroundf.

/// A motor command: v rounded and clamped to -255..255.
inline ROVERNAV_NOINLINE int16_t clamp_pwm(float v) {
  if (magnitude_above(v, 255.0f)) return sign_bit(v) ? -255 : 255;
  return static_cast<int16_t>(lroundf(v));
}

/// v rounded into 0..65535 (0 for NaN), for the wire.
inline ROVERNAV_NOINLINE uint16_t saturate_u16(float v) {
  if (!positive(v)) return 0;
  if (float_bits(v) > float_bits(65535.0f)) return 65535;   // positive: no sign bit, no NaN
  return static_cast<uint16_t>(lroundf(v));
}

/// v rounded into -32768..32767, for the wire.
inline ROVERNAV_NOINLINE int16_t saturate_i16(float v) {
  if (sign_bit(v)) {
    if (magnitude_above(v, 32768.0f)) return -32768;
  } else if (magnitude_above(v, 32767.0f)) {
    return 32767;
  }
  return static_cast<int16_t>(lroundf(v));
}

}  // namespace core
}  // namespace rovernav
