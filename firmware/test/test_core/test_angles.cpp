// The angle helpers against the C library, over the whole plane.
#include <doctest/doctest.h>
#include <math.h>
#include <string.h>

#include "angles.h"
#include "float_ops.h"
#include "rover.h"

using namespace rovernav::core;

TEST_CASE("fast_atan2 is within 1.2e-5 rad of atan2 in every direction and at every scale") {
  double worst = 0.0;
  int checked = 0;
  const float scales[] = {1e-3f, 0.37f, 1.0f, 250.0f, 3.3e4f};
  for (float scale : scales) {
    for (int i = 0; i < 3600; ++i) {   // every 0.1 degree, plus an offset that hits no axis exactly
      const double a = (i + 0.37) * (2.0 * M_PI / 3600.0);
      const float y = static_cast<float>(scale * sin(a)), x = static_cast<float>(scale * cos(a));
      const double err = fabs(static_cast<double>(fast_atan2(y, x)) - atan2(static_cast<double>(y), static_cast<double>(x)));
      const double wrapped = err > M_PI ? 2.0 * M_PI - err : err;   // -pi and pi are one direction
      if (wrapped > worst) worst = wrapped;
      ++checked;
    }
  }
  MESSAGE("worst error " << worst << " rad over " << checked << " directions");
  CHECK(worst <= 1.2e-5);
}

TEST_CASE("fast_atan2 on the axes, at the origin and on the diagonals") {
  const float q = static_cast<float>(M_PI / 4.0);
  CHECK(fast_atan2(0.0f, 0.0f) == 0.0f);
  CHECK(fast_atan2(0.0f, 5.0f) == 0.0f);
  CHECK(fast_atan2(5.0f, 0.0f) == doctest::Approx(2 * q).epsilon(1e-6));
  CHECK(fast_atan2(-5.0f, 0.0f) == doctest::Approx(-2 * q).epsilon(1e-6));
  CHECK(fast_atan2(0.0f, -5.0f) == doctest::Approx(4 * q).epsilon(1e-6));
  CHECK(fast_atan2(1.0f, 1.0f) == doctest::Approx(q).epsilon(2e-5));
  CHECK(fast_atan2(-1.0f, -1.0f) == doctest::Approx(-3 * q).epsilon(2e-5));
  // +x is 90 degrees clockwise from +y; -y is 180 degrees.
  CHECK(bearing_rad(Point{100, 200}, Point{110, 200}) == doctest::Approx(2 * q).epsilon(1e-6));
  CHECK(bearing_rad(Point{100, 200}, Point{100, 150}) == doctest::Approx(4 * q).epsilon(1e-6));
}

TEST_CASE("wrap_rad: into (-pi, pi] within four turns; NaN and huge values do not stall it") {
  int out_of_range = 0, turned = 0, checked = 0;
  for (int i = -3600; i <= 3600; ++i) {   // -4 to +4 turns, every 0.4 degree
    const float a = static_cast<float>(i * (8.0 * M_PI / 7200.0) + 1e-3);
    const float w = wrap_rad(a);
    if (!(w > -kPi && w <= kPi)) ++out_of_range;
    // The same direction: a whole number of turns apart.
    const double turns = (static_cast<double>(a) - w) / (2.0 * M_PI);
    if (!(fabs(turns - round(turns)) < 1e-5)) ++turned;
    ++checked;
  }
  MESSAGE(checked << " angles from -4 to +4 turns");
  CHECK(out_of_range == 0);
  CHECK(turned == 0);
  CHECK(wrap_rad(kPi) == kPi);
  CHECK(wrap_rad(-kPi) == doctest::Approx(kPi));
  CHECK(wrap_rad(0.5f) == 0.5f);
  CHECK(isnan(wrap_rad(NAN)));
  CHECK(wrap_rad(1e30f) == 1e30f);   // beyond the bounded loop: returned, not looped on
}

TEST_CASE("positive is v > 0.0f: zeros, denormals, infinities, NaNs and a sweep of every bit pattern's class") {
  const uint32_t edges[] = {0x00000000u, 0x00000001u, 0x007FFFFFu, 0x00800000u, 0x3F800000u, 0x7F7FFFFFu,
                            0x7F800000u, 0x7F800001u, 0x7FC00000u, 0x7FFFFFFFu, 0x80000000u, 0x80000001u,
                            0xBF800000u, 0xFF800000u, 0xFF800001u, 0xFFC00000u, 0xFFFFFFFFu};
  for (uint32_t b : edges) {
    float v;
    memcpy(&v, &b, sizeof v);
    CHECK(positive(v) == (v > 0.0f));
  }
  // Every 4,099th pattern (a prime stride: every exponent, both signs, mantissas of all kinds);
  // all 2^32 agree too, which takes a native build some seconds.
  uint32_t wrong = 0;
  for (uint64_t i = 0; i <= 0xFFFFFFFFull; i += 4099) {
    const uint32_t b = static_cast<uint32_t>(i);
    float v;
    memcpy(&v, &b, sizeof v);
    if (positive(v) != (v > 0.0f)) ++wrong;
  }
  CHECK(wrong == 0);
}
