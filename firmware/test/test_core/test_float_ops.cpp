// The wire's saturating conversions: rounding as lroundf, the clamps, and a NaN sent to 0.
#include <doctest/doctest.h>
#include <math.h>

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
