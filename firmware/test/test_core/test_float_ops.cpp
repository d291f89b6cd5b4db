// The wire's saturating conversions: rounding as lroundf, the clamps, and a NaN sent to 0.
#include <doctest/doctest.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "float_ops.h"

using namespace rovernav::core;

TEST_CASE("the wire's saturations round, clamp, and send a NaN to 0") {
  CHECK(saturate_i16(1.5f) == 2);
  CHECK(saturate_i16(-1.5f) == -2);
  CHECK(saturate_i16(0.49f) == 0);
  CHECK(saturate_i16(40000.0f) == 32767);
  CHECK(saturate_i16(-40000.0f) == -32768);
  CHECK(saturate_i16(NAN) == 0);
  CHECK(saturate_u16(65535.4f) == 65535);
  CHECK(saturate_u16(70000.0f) == 65535);
  CHECK(saturate_u16(-3.0f) == 0);
  CHECK(saturate_u16(NAN) == 0);
  CHECK(clamp_pwm(254.6f) == 255);
  CHECK(clamp_pwm(-300.0f) == -255);
  CHECK(clamp_pwm(-12.5f) == -13);
  CHECK(clamp_pwm(NAN) == 0);
}

TEST_CASE("the comparisons on the bits agree with the float comparisons on every 997th bit pattern") {
  const float limits[] = {0.5f, 20.0f, 45.0f, 60.0f, 100.0f, 150.0f, 25.0f};
  long checked = 0, wrong = 0;
  for (uint64_t b = 0; b <= 0xFFFFFFFFull; b += 997) {
    const uint32_t bits = static_cast<uint32_t>(b);
    float v;
    memcpy(&v, &bits, sizeof v);
    for (float limit : limits) {
      if (at_least(v, limit) != (v >= limit)) ++wrong;
      if (magnitude_at_most(v, limit) != (fabsf(v) <= limit)) ++wrong;
      if (magnitude_above(v, limit) != (fabsf(v) > limit)) ++wrong;
      ++checked;
    }
  }
  // And the edges themselves: each limit, its neighbours, the zeros, the infinities.
  for (float limit : limits) {
    const float edge[] = {limit, nextafterf(limit, 0.0f), nextafterf(limit, INFINITY), -limit, 0.0f, -0.0f, INFINITY, -INFINITY, NAN};
    for (float v : edge) {
      if (at_least(v, limit) != (v >= limit)) ++wrong;
      if (magnitude_at_most(v, limit) != (fabsf(v) <= limit)) ++wrong;
      ++checked;
    }
  }
  CHECK(checked > 30000000L);
  CHECK(wrong == 0);
}
