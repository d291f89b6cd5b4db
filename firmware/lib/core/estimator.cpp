#include "estimator.h"

#include <math.h>

#include "angles.h"

namespace rovernav {
namespace core {

namespace {
// Heading noise of a camera fix: the seed's markers are about 100 mm apart, so a few
// millimetres of centroid noise turn into about a degree.
const float kFixHeadingSdRad = 1.0f * kRadPerDeg;
// Innovation gate: squared Mahalanobis distance beyond which a fix is not believed
// (chi-square, 3 degrees of freedom, p < 1e-5).
const float kGateChi2 = 25.0f;
enum { XX = 0, XY = 1, XT = 2, YY = 3, YT = 4, TT = 5 };
// Where entry (row, column) of the symmetric P is stored.
const uint8_t kIndex[3][3] = {{XX, XY, XT}, {XY, YY, YT}, {XT, YT, TT}};
}  // namespace

void Estimator::reset() {
  initialised_ = false;
  rejects_in_row_ = 0;
  rejected_total_ = 0;
}

void Estimator::predict(float d, float dth, float var_d, float var_th, uint32_t now_ms) {
  if (!initialised_) return;
  const float mid = th_ + 0.5f * dth;
  const float s = sinf(mid), c = cosf(mid);
  x_ += d * s;
  y_ += d * c;
  th_ = wrap_rad(th_ + dth);
  // The same increments, without the fixes' corrections (so in the estimate's frame).
  odo_x_ += d * s;
  odo_y_ += d * c;
  odo_th_ = wrap_rad(odo_th_ + dth);

  // P' = Fq P Fq^T + Fv V Fv^T, written out for the symmetric 3x3 P.
  const float a = d * c, b = -d * s;
  float* P = p_;
  const float xx = P[XX] + 2.0f * a * P[XT] + a * a * P[TT];
  const float xy = P[XY] + a * P[YT] + b * P[XT] + a * b * P[TT];
  const float xt = P[XT] + a * P[TT];
  const float yy = P[YY] + 2.0f * b * P[YT] + b * b * P[TT];
  const float yt = P[YT] + b * P[TT];
  P[XX] = xx + s * s * var_d;
  P[XY] = xy + s * c * var_d;
  P[XT] = xt;
  P[YY] = yy + c * c * var_d;
  P[YT] = yt;
  P[TT] += var_th;

  if (history_count_ == 0 || now_ms - history_last_ms_ >= kHistoryPeriodMs) {
    Past& h = history_[history_next_];
    h.x_mm = static_cast<int16_t>(lroundf(odo_x_));
    h.y_mm = static_cast<int16_t>(lroundf(odo_y_));
    h.heading_cdeg = rad_to_cdeg(odo_th_);
    h.t_ms = static_cast<uint16_t>(now_ms);
    history_next_ = static_cast<uint8_t>((history_next_ + 1) % kHistory);
    if (history_count_ < kHistory) ++history_count_;
    history_last_ms_ = now_ms;
  }
}

void Estimator::odometry_since(uint32_t t_ms, uint32_t now_ms, float& dx, float& dy, float& dth) const {
  dx = dy = dth = 0.0f;
  const int32_t want = static_cast<int32_t>(now_ms - t_ms);
  if (want <= 0 || history_count_ == 0) return;
  // Bracket t_ms: the oldest sample no older than it ("newer", the odometry now at worst) and
  // the youngest sample at least as old ("older"); interpolate between them.
  float nx = odo_x_, ny = odo_y_, nt = odo_th_;
  int32_t n_age = 0, o_age = -1;
  float ox = 0, oy = 0, ot = 0;
  for (uint8_t i = 0; i < history_count_; ++i) {
    const Past& h = history_[i];
    const int32_t age = static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - h.t_ms);
    const bool newer = age <= want && age > n_age;
    const bool older = age >= want && (o_age < 0 || age < o_age);
    if (!newer && !older) continue;
    const float hx = h.x_mm, hy = h.y_mm, ht = cdeg_to_rad(h.heading_cdeg);
    if (newer) {
      n_age = age;
      nx = hx, ny = hy, nt = ht;
    } else {
      o_age = age;
      ox = hx, oy = hy, ot = ht;
    }
  }
  float px = nx, py = ny, pt = nt;
  if (o_age > n_age) {
    const float f = static_cast<float>(want - n_age) / static_cast<float>(o_age - n_age);
    px += f * (ox - nx);
    py += f * (oy - ny);
    pt += f * wrap_rad(ot - nt);
  }
  dx = odo_x_ - px;
  dy = odo_y_ - py;
  dth = wrap_rad(odo_th_ - pt);
}

FixResult Estimator::update(const PoseFix& fix, uint32_t now_ms) {
  const float zx = fix.x_mm, zy = fix.y_mm, zt = cdeg_to_rad(fix.heading_cdeg);
  const float r_pos = fix.sd_mm > 0 ? static_cast<float>(fix.sd_mm) * static_cast<float>(fix.sd_mm) : 4.0f;
  const float r_th = kFixHeadingSdRad * kFixHeadingSdRad;
  if (!initialised_) {
    initialised_ = true;
    rejects_in_row_ = 0;
    history_count_ = 0;
    x_ = zx;
    y_ = zy;
    th_ = zt;
    for (uint8_t i = 0; i < 6; ++i) p_[i] = 0.0f;
    p_[XX] = p_[YY] = r_pos;
    p_[TT] = r_th;
    return FixResult::Initialised;
  }
  // Innovation against the pose when the frame was taken.
  float ox = 0, oy = 0, ot = 0;
  odometry_since(fix.taken_ms, now_ms, ox, oy, ot);
  const float hx = x_ - ox, hy = y_ - oy, ht = th_ - ot;
  const float v0 = zx - hx, v1 = zy - hy;
  last_innovation_mm_ = sqrtf(v0 * v0 + v1 * v1);

  // H = I and R diagonal, so the update is done one component at a time: three scalar updates
  // give exactly the batch result, in a loop that fits the Uno's flash. It runs on a copy, so
  // that a fix failing the gate changes nothing. The gate statistic is the sum of the normalised
  // squared innovations of the sequence, which equals the batch's v^T S^-1 v.
  float q[3] = {x_, y_, th_};
  float P[3][3];
  for (uint8_t r = 0; r < 3; ++r)
    for (uint8_t c = 0; c < 3; ++c) P[r][c] = p_[kIndex[r][c]];
  const float z[3] = {zx, zy, zt};
  const float h[3] = {hx, hy, ht};
  const float noise[3] = {r_pos, r_pos, r_th};
  float chi2 = 0.0f;
  for (uint8_t j = 0; j < 3; ++j) {
    // The innovation of component j against the (already partly corrected) past pose.
    float v = z[j] - (h[j] + (q[j] - (j == 0 ? x_ : (j == 1 ? y_ : th_))));
    if (j == 2) v = wrap_rad(v);
    const float sj = P[j][j] + noise[j];
    if (!(sj > 0.0f)) return FixResult::Rejected;
    chi2 += v * v / sj;
    float k[3];
    for (uint8_t r = 0; r < 3; ++r) k[r] = P[r][j] / sj;
    for (uint8_t r = 0; r < 3; ++r) q[r] += k[r] * v;
    float row[3];
    for (uint8_t c = 0; c < 3; ++c) row[c] = P[j][c];
    for (uint8_t r = 0; r < 3; ++r)
      for (uint8_t c = 0; c < 3; ++c) P[r][c] -= k[r] * row[c];
  }
  if (!(chi2 <= kGateChi2)) {
    ++rejected_total_;
    if (++rejects_in_row_ < kMaxRejects) return FixResult::Rejected;
    // The camera has insisted: we were wrong (moved by hand, or lost). Start again from it.
    const uint16_t rejected = rejected_total_;
    initialised_ = false;
    const FixResult r = update(fix, now_ms);
    rejected_total_ = rejected;
    last_correction_mm_ = last_innovation_mm_;
    return r;
  }
  rejects_in_row_ = 0;
  const float dx = q[0] - x_, dy = q[1] - y_;
  x_ = q[0];
  y_ = q[1];
  th_ = wrap_rad(q[2]);
  last_correction_mm_ = sqrtf(dx * dx + dy * dy);
  for (uint8_t r = 0; r < 3; ++r)
    for (uint8_t c = r; c < 3; ++c) p_[kIndex[r][c]] = 0.5f * (P[r][c] + P[c][r]);
  return FixResult::Accepted;
}

float Estimator::position_sd_mm() const {
  // Largest eigenvalue of the 2x2 position block.
  const float a = p_[XX], b = p_[XY], d = p_[YY];
  const float half_tr = 0.5f * (a + d);
  const float disc = sqrtf(0.25f * (a - d) * (a - d) + b * b);
  const float lmax = half_tr + disc;
  return lmax > 0.0f ? sqrtf(lmax) : 0.0f;
}

}  // namespace core
}  // namespace rovernav
