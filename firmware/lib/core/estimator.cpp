#include "estimator.h"

#include <math.h>
#include <string.h>

#include "angles.h"
#include "float_ops.h"
#include "progmem.h"

namespace rovernav {
namespace core {

namespace {
// Heading noise of a camera fix: the seed's markers are about 100 mm apart, so a few
// millimetres of centroid noise turn into about a degree.
const float kFixHeadingSdRad = 1.0f * kRadPerDeg;
const float kFixHeadingVar = kFixHeadingSdRad * kFixHeadingSdRad;
// Innovation gate: squared Mahalanobis distance beyond which a fix is not believed
// (chi-square, 3 degrees of freedom, p < 1e-5).
const float kGateChi2 = 25.0f;
enum { X = 0, Y = 1, T = 2 };  // the pose q
enum { XX = Estimator::kXX, XY = Estimator::kXY, YY = Estimator::kYY, XT = Estimator::kXT, YT = Estimator::kYT, TT = Estimator::kTT };
// Where entry (row, column) of the symmetric P is stored, by 3 * row + column.
const uint8_t kIndex[9] ROVERNAV_PROGMEM = {XX, XY, XT, XY, YY, YT, XT, YT, TT};

// The sequential scalar updates of the pose q and the full covariance P (row-major, 3x3) by the
// fix z, seen against h, the pose when its frame was taken; q0 is the pose before the update.
// Returns the gate statistic: the sum of the normalised squared innovations of the sequence,
// which equals the batch's v^T S^-1 v. Negative if an innovation variance is not positive.
// (A function of its own: its few locals stay within the AVR's short stack offsets.)
ROVERNAV_NOINLINE float sequential_update(const float* z, const float* h, const float* q0, float r_pos, float* q, float* P) {
  float chi2 = 0.0f;
  for (uint8_t j = 0; j < 3; ++j) {
    // The innovation of component j against the (already partly corrected) past pose.
    float v = z[j] - (h[j] + (q[j] - q0[j]));
    if (j == T) v = wrap_rad(v);
    const float* pj = P + 3 * j;
    const float sj = pj[j] + (j == T ? kFixHeadingVar : r_pos);
    if (!positive(sj)) return -1.0f;
    const float inv_sj = 1.0f / sj;   // one division, not four (28 us each on the Uno)
    chi2 += v * v * inv_sj;
    // P -= k P[j], k = P[., j] / sj. Row j goes last: the other rows need it unchanged.
    for (uint8_t i = 1; i <= 3; ++i) {
      const uint8_t r = static_cast<uint8_t>(j + i < 3 ? j + i : j + i - 3);
      float* row = P + 3 * r;
      const float k = row[j] * inv_sj;
      q[r] += k * v;
      for (uint8_t c = 0; c < 3; ++c) row[c] -= k * pj[c];
    }
  }
  return chi2;
}
}  // namespace

void Estimator::reset() {
  initialised_ = false;
  rejects_in_row_ = 0;
  clear_rejected();
}

void Estimator::predict(float d, float dth, float var_d, float var_th, uint32_t now_ms) {
  if (!initialised_) return;
  const float mid = q_[T] + 0.5f * dth;
  const float s = sinf(mid), c = cosf(mid);
  const float dx = d * s, dy = d * c;
  advance(q_, dx, dy, dth);
  // The same increments, without the fixes' corrections (so in the estimate's frame).
  advance(odo_, dx, dy, dth);

  // P' = Fq P Fq^T + Fv V Fv^T for the symmetric 3x3 P. With e = (d cos, -d sin), how the
  // position moves with the heading, and the column c = (P_xt, P_yt): c' = c + e P_tt, and each
  // entry of the position block gains e_i c_j + e_j c'_i (the products of Fq P Fq^T, regrouped)
  // and the distance noise g_i g_j var_d, g = (sin, cos). A loop over the block's three entries
  // (xx, xy, yy) is a third of the flash the products written out took.
  const float e[2] = {dy, -dx};   // -(d sin) is (-d) sin exactly: the products above serve
  const float g[2] = {s, c};
  float* P = p_;
  static_assert(XT + 1 == YT && XX + 1 == XY && XY + 1 == YY, "the column and the block lie in order");
  float c_old[2];
  memcpy(c_old, P + XT, sizeof c_old);
  for (uint8_t i = 0; i < 2; ++i) P[XT + i] += e[i] * P[TT];
  const float* c_new = P + XT;
  for (uint8_t k = 0; k < 3; ++k) {
    const uint8_t i = static_cast<uint8_t>(k >> 1), j = static_cast<uint8_t>((k + 1) >> 1);  // xx, xy, yy
    P[XX + k] += e[i] * c_old[j] + e[j] * c_new[i] + g[i] * g[j] * var_d;
  }
  P[TT] += var_th;

  if (history_count_ == 0 || static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - history_last_ms_) >= kHistoryPeriodMs) {
    Past& h = history_[history_next_];
    // A loop over x and y: the two rounds written out took 16 bytes more with avr-gcc 5.4 (the same with 7.3).
    for (uint8_t i = 0; i < 2; ++i) h.xy_mm[i] = static_cast<int16_t>(lroundf(odo_[i]));
    h.heading_cdeg = rad_to_cdeg(odo_[T]);
    h.t_ms = static_cast<uint16_t>(now_ms);
    history_next_ = history_next_ + 1 < kHistory ? static_cast<uint8_t>(history_next_ + 1) : 0;   // a wrap, not a division
    if (history_count_ < kHistory) ++history_count_;
    history_last_ms_ = static_cast<uint16_t>(now_ms);
  }
}

ROVERNAV_NOINLINE void Estimator::advance(float* pose, float dx, float dy, float dth) {
  pose[X] += dx;
  pose[Y] += dy;
  pose[T] = wrap_rad(pose[T] + dth);
}

ROVERNAV_NOINLINE void Estimator::odometry_since(uint32_t t_ms, uint32_t now_ms, float* d) const {
  d[X] = d[Y] = d[T] = 0.0f;
  const int32_t want = static_cast<int32_t>(now_ms - t_ms);
  if (want <= 0) return;
  // The history is in time order: walk back from the odometry now (age 0) to the first sample
  // at least `want` old, and interpolate between it and the one after it ("newer"). With none
  // that old, the oldest sample will do.
  float n[3];
  memcpy(n, odo_, sizeof n);
  int32_t n_age = 0;
  uint8_t at = history_next_;
  for (uint8_t k = 1; k <= history_count_; ++k) {
    at = at > 0 ? static_cast<uint8_t>(at - 1) : static_cast<uint8_t>(kHistory - 1);   // back one, a wrap (no division)
    const Past& h = history_[at];
    const int32_t age = static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - h.t_ms);
    const float o[3] = {to_float(h.xy_mm[X]), to_float(h.xy_mm[Y]), cdeg_to_rad(h.heading_cdeg)};
    if (age >= want) {
      if (age > n_age) {
        const float f = static_cast<float>(want - n_age) / static_cast<float>(age - n_age);
        for (uint8_t i = 0; i < 3; ++i) n[i] += f * (i == T ? wrap_rad(o[T] - n[T]) : o[i] - n[i]);
      }
      break;
    }
    for (uint8_t i = 0; i < 3; ++i) n[i] = o[i];
    n_age = age;
  }
  for (uint8_t i = 0; i < 3; ++i) d[i] = odo_[i] - n[i];
  d[T] = wrap_rad(d[T]);
}

FixResult Estimator::update(const PoseFix& fix, uint32_t now_ms) {
  const float z[3] = {to_float(fix.x_mm), to_float(fix.y_mm), cdeg_to_rad(fix.heading_cdeg)};
  const float r_pos = fix.sd_mm > 0 ? to_float(fix.sd_mm) * to_float(fix.sd_mm) : 4.0f;
  if (!initialised_) return start_from(z, r_pos);
  // Innovation against the pose when the frame was taken: the estimate less the odometry since.
  float h[3];
  odometry_since(fix.taken_ms, now_ms, h);
  for (uint8_t i = 0; i < 3; ++i) h[i] = q_[i] - h[i];
  last_innovation_mm_ = saturate_u16(length(z[X] - h[X], z[Y] - h[Y]));

  switch (correct(z, h, r_pos)) {
    case Correction::Taken:
      rejects_in_row_ = 0;
      return FixResult::Accepted;
    case Correction::Degenerate:
      return FixResult::Rejected;  // a degenerate covariance: not the fix's fault
    default:
      break;
  }
  count_rejected();
  if (++rejects_in_row_ < kMaxRejects) return FixResult::Rejected;
  // The camera has insisted: we were wrong (moved by hand, or lost). Start again from it.
  return start_from(z, r_pos);
}

// Out of line: pasted into update(), the copies' 48 bytes joined z, h and the spills in one
// frame, past the AVR's short (Y+63) stack offsets: a pair of pointer moves round every access.
ROVERNAV_NOINLINE Estimator::Correction Estimator::correct(const float* z, const float* h, float r_pos) {
  // H = I and R diagonal, so the update is done one component at a time: three scalar updates
  // give exactly the batch result, in a loop that fits the Uno's flash. It runs on a copy, so
  // that a fix failing the gate changes nothing.
  float q[3];
  memcpy(q, q_, sizeof q);   // a copy loop: the three floats written out took 100 bytes
  float P[9];
  for (uint8_t i = 0; i < 9; ++i) P[i] = p_[flash_read_u8(&kIndex[i])];
  const float chi2 = sequential_update(z, h, q_, r_pos, q, P);
  // On the bits, no library call: the only negative float sequential_update() returns is its
  // -1; the rest are +0, positive or NaN, whose bits lie above 25's for exactly those not <= 25.
  if (float_bits(chi2) == float_bits(-1.0f)) return Correction::Degenerate;
  if (float_bits(chi2) > float_bits(kGateChi2)) return Correction::Gated;
  q[T] = wrap_rad(q[T]);
  memcpy(q_, q, sizeof q_);
  // Back into the six entries (the lower triangle's copy of an off-diagonal entry, written last,
  // is kept: the two differ by rounding only).
  for (uint8_t i = 0; i < 9; ++i) p_[flash_read_u8(&kIndex[i])] = P[i];
  return Correction::Taken;
}

ROVERNAV_NOINLINE FixResult Estimator::start_from(const float* z, float r_pos) {
  initialised_ = true;
  rejects_in_row_ = 0;
  history_count_ = 0;
  for (uint8_t i = 0; i < 3; ++i) q_[i] = z[i];
  for (uint8_t i = 0; i < 6; ++i) p_[i] = 0.0f;
  p_[XX] = p_[YY] = r_pos;
  p_[TT] = kFixHeadingVar;
  return FixResult::Initialised;
}

float Estimator::position_sd_mm() const {
  // Largest eigenvalue of the 2x2 position block.
  const float a = p_[XX], b = p_[XY], d = p_[YY];
  const float half_tr = 0.5f * (a + d);
  const float disc = length(0.5f * (a - d), b);
  return sqrt_or_zero(half_tr + disc);
}

}  // namespace core
}  // namespace rovernav
