// The rounding helpers against the C library: round_to_i32 stands in for lroundf on the image.
#include <doctest/doctest.h>
#include <math.h>

#include "float_ops.h"

using namespace rovernav::core;

TEST_CASE("round_to_i32 rounds as lroundf, halves away from zero, and a NaN to 0") {
  const float exact[] = {0.0f, -0.0f, 0.5f, -0.5f, 1.5f, -1.5f, 2.5f, -2.5f, 0.49f, -0.49f, 0.51f, -0.51f,
                         254.5f, -254.5f, 32767.4f, -32768.4f, 65535.49f, 1e6f, -1e6f};
  for (float v : exact) {
    CAPTURE(v);
    CHECK(round_to_i32(v) == lroundf(v));
  }
  int checked = 0;
  for (int i = -200000; i <= 200000; ++i) {   // every 0.01 across +-2,000, halves and near-halves among them
    const float v = static_cast<float>(i) * 0.01f;
    if (round_to_i32(v) != lroundf(v)) {
      CAPTURE(v);
      CHECK(round_to_i32(v) == lroundf(v));
    }
    ++checked;
  }
  CHECK(checked == 400001);
  CHECK(round_to_i32(NAN) == 0);
  CHECK(round_to_i32(-NAN) == 0);
}

TEST_CASE("the wire's saturations round, clamp, and send a NaN to 0") {
  CHECK(saturate_i16(1.5f) == 2);
  CHECK(saturate_i16(-1.5f) == -2);
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
