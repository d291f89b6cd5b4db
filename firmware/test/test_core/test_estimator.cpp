// The estimator: dead reckoning with the covariance of Russo's Fq/Fv, camera fixes as an EKF
// update, latency compensation, and the outlier gate.
#include <doctest.h>
#include <math.h>

#include "angles.h"
#include "estimator.h"

using rovernav::core::Estimator;
using rovernav::core::FixResult;
using rovernav::core::PoseFix;
using rovernav::core::kRadPerDeg;

namespace {
PoseFix fix(int16_t x, int16_t y, int16_t cdeg, uint32_t taken, uint8_t sd = 2) {
  PoseFix f;
  f.x_mm = x;
  f.y_mm = y;
  f.heading_cdeg = cdeg;
  f.sd_mm = sd;
  f.taken_ms = taken;
  return f;
}
}  // namespace

TEST_CASE("no pose until the first fix; the first fix initialises it") {
  Estimator e;
  e.reset();
  CHECK_FALSE(e.initialised());
  e.predict(10, 0, 1, 0, 0);
  CHECK(e.update(fix(500, 600, 9000, 0), 0) == FixResult::Initialised);
  CHECK(e.x_mm() == doctest::Approx(500));
  CHECK(e.y_mm() == doctest::Approx(600));
  CHECK(e.heading_rad() == doctest::Approx(90 * kRadPerDeg));
}

TEST_CASE("dead reckoning: heading 0 is +y, 90 degrees is +x (clockwise)") {
  Estimator e;
  e.update(fix(0, 0, 0, 0), 0);
  e.predict(100, 0, 0, 0, 10);
  CHECK(e.x_mm() == doctest::Approx(0).epsilon(1e-3));
  CHECK(e.y_mm() == doctest::Approx(100));
  e.predict(0, 90 * kRadPerDeg, 0, 0, 20);
  e.predict(50, 0, 0, 0, 30);
  CHECK(e.x_mm() == doctest::Approx(50));
  CHECK(e.y_mm() == doctest::Approx(100));
}

TEST_CASE("covariance follows P' = Fq P Fq^T + Fv V Fv^T: heading doubt becomes cross-track doubt") {
  Estimator e;
  e.update(fix(0, 0, 0, 0, 1), 0);
  const float xx0 = e.p(Estimator::kXX), yy0 = e.p(Estimator::kYY), tt0 = e.p(Estimator::kTT);
  // Drive 1 m north with no distance noise: only the heading's variance spreads x (cross-track).
  for (int i = 0; i < 100; ++i) e.predict(10, 0, 0, 0, static_cast<uint32_t>(i));
  const float expected_xx = xx0 + tt0 * 1000.0f * 1000.0f;  // var(x) grows by L^2 var(theta)
  CHECK(e.p(Estimator::kXX) == doctest::Approx(expected_xx).epsilon(0.02));
  CHECK(e.p(Estimator::kYY) == doctest::Approx(yy0).epsilon(1e-3));     // along-track unchanged
  CHECK(e.p(Estimator::kXT) == doctest::Approx(1000.0f * tt0).epsilon(0.02));  // x-theta correlation
  // Distance noise goes along the track only.
  Estimator f;
  f.update(fix(0, 0, 9000, 0, 1), 0);
  const float f_xx0 = f.p(Estimator::kXX);
  f.predict(100, 0, 50, 0, 1);
  CHECK(f.p(Estimator::kXX) == doctest::Approx(f_xx0 + 50).epsilon(1e-3));  // heading east: along-track is x
}

TEST_CASE("a fix pulls the estimate to it in proportion to the uncertainties") {
  Estimator e;
  e.update(fix(0, 0, 0, 0, 2), 0);
  for (int i = 0; i < 100; ++i) e.predict(10, 0, 10, 0, static_cast<uint32_t>(i * 10));  // var grows to ~1000 mm^2
  const float before = e.y_mm();
  CHECK(e.update(fix(0, 1030, 0, 1000, 2), 1000) == FixResult::Accepted);
  CHECK(e.y_mm() > before + 25.0f);  // mostly believes the fix (4 mm^2 against ~1000)
  CHECK(e.y_mm() < 1030.5f);
  CHECK(e.position_sd_mm() < 3.0f);
}

TEST_CASE("a fix is applied to the pose at the time its frame was taken, not the pose now") {
  Estimator lagging, compensated;
  lagging.update(fix(0, 0, 0, 0, 2), 0);
  compensated.update(fix(0, 0, 0, 0, 2), 0);
  // Moving north at 100 mm/s for 1 s, in 10 ms steps, with a model 10 % short.
  for (uint32_t t = 10; t <= 1000; t += 10) {
    lagging.predict(0.9f, 0, 0.5f, 0, t);
    compensated.predict(0.9f, 0, 0.5f, 0, t);
  }
  // The camera saw y = 80 mm at t = 800 ms (its frame is 200 ms old when it arrives).
  lagging.update(fix(0, 80, 0, 1000, 2), 1000);      // pretends the frame is from now
  compensated.update(fix(0, 80, 0, 800, 2), 1000);   // knows when it was taken
  // Truth now: 100 mm. Applied as if current, the fix drags the estimate back towards 80.
  CHECK(fabsf(compensated.y_mm() - 100.0f) < fabsf(lagging.y_mm() - 100.0f));
  CHECK(fabsf(compensated.y_mm() - 100.0f) < 4.0f);
}

TEST_CASE("an implausible fix is rejected; a camera that insists resets the estimate") {
  Estimator e;
  e.update(fix(0, 0, 0, 0, 2), 0);
  CHECK(e.update(fix(900, 900, 0, 10, 2), 10) == FixResult::Rejected);
  CHECK(e.x_mm() == doctest::Approx(0));
  for (int i = 1; i < Estimator::kMaxRejects - 1; ++i) CHECK(e.update(fix(900, 900, 0, 10, 2), 10) == FixResult::Rejected);
  CHECK(e.update(fix(900, 900, 0, 10, 2), 10) == FixResult::Initialised);
  CHECK(e.x_mm() == doctest::Approx(900));
  CHECK(e.rejected_fixes() == Estimator::kMaxRejects);
}

TEST_CASE("headings wrap: a fix at 179 degrees and an estimate at -179 are 2 degrees apart") {
  Estimator e;
  e.update(fix(0, 0, -17900, 0, 2), 0);
  CHECK(e.update(fix(0, 0, 17900, 10, 2), 10) == FixResult::Accepted);
  CHECK(fabsf(fabsf(e.heading_rad()) - 180.0f * kRadPerDeg) < 1.5f * kRadPerDeg);
}

TEST_CASE("a fix's update equals the batch Kalman update, correlations included") {
  // A turn and a drive give a full covariance (x, y and heading all correlated); the filter's
  // three scalar updates must land where the textbook K = P (P + R)^-1 does.
  Estimator e;
  e.update(fix(100, 200, 3000, 0, 3), 0);
  for (uint32_t t = 10; t <= 1000; t += 10) e.predict(2.0f, 0.3f * kRadPerDeg, 2.0f, 1e-5f, t);
  const int idx[3][3] = {{Estimator::kXX, Estimator::kXY, Estimator::kXT},
                         {Estimator::kXY, Estimator::kYY, Estimator::kYT},
                         {Estimator::kXT, Estimator::kYT, Estimator::kTT}};
  double P[3][3], S[3][3], Si[3][3], K[3][3];
  const double r[3] = {16.0, 16.0, double(kRadPerDeg) * double(kRadPerDeg)};  // sd 4 mm, 1 degree
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      P[i][j] = e.p(static_cast<uint8_t>(idx[i][j]));
      S[i][j] = P[i][j] + (i == j ? r[i] : 0.0);
    }
  REQUIRE(P[0][1] != 0.0);
  REQUIRE(P[0][2] != 0.0);
  REQUIRE(P[1][2] != 0.0);
  const double det = S[0][0] * (S[1][1] * S[2][2] - S[1][2] * S[2][1]) -
                     S[0][1] * (S[1][0] * S[2][2] - S[1][2] * S[2][0]) +
                     S[0][2] * (S[1][0] * S[2][1] - S[1][1] * S[2][0]);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
      Si[i][j] = (S[a][c] * S[b][d] - S[a][d] * S[b][c]) / det;  // adjugate: cofactor (j, i)
    }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) K[i][j] = P[i][0] * Si[0][j] + P[i][1] * Si[1][j] + P[i][2] * Si[2][j];
  const double q[3] = {e.x_mm(), e.y_mm(), e.heading_rad()};
  const int16_t zx = static_cast<int16_t>(lround(q[0] + 6.0)), zy = static_cast<int16_t>(lround(q[1] - 5.0));
  const double rad_per_cdeg = double(kRadPerDeg) / 100.0;
  const int16_t zt = static_cast<int16_t>(lround(q[2] / rad_per_cdeg + 80.0));
  const double v[3] = {zx - q[0], zy - q[1], zt * rad_per_cdeg - q[2]};
  REQUIRE(e.update(fix(zx, zy, zt, 1000, 4), 1000) == FixResult::Accepted);
  const double x = q[0] + K[0][0] * v[0] + K[0][1] * v[1] + K[0][2] * v[2];
  const double y = q[1] + K[1][0] * v[0] + K[1][1] * v[1] + K[1][2] * v[2];
  const double th = q[2] + K[2][0] * v[0] + K[2][1] * v[1] + K[2][2] * v[2];
  CHECK(e.x_mm() == doctest::Approx(x).epsilon(1e-5));
  CHECK(e.y_mm() == doctest::Approx(y).epsilon(1e-5));
  CHECK(e.heading_rad() == doctest::Approx(th).epsilon(1e-4));
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) {
      const double expected = P[i][j] - (K[i][0] * P[0][j] + K[i][1] * P[1][j] + K[i][2] * P[2][j]);
      CHECK(e.p(static_cast<uint8_t>(idx[i][j])) == doctest::Approx(expected).epsilon(1e-3).scale(1e-6));
    }
}
