// Pose estimator: dead reckoning from the gyro and the wheels (or a speed model of the motor
// commands), and an extended Kalman filter that takes the overhead camera's fixes.
//
// State q = (x, y, theta): millimetres in the arena frame, theta clockwise from +y. Motion over
// one step with travelled distance d and heading change dtheta (Russo 2024, eq. 4.1, in our
// heading convention, evaluated at the mid-step heading):
//     x' = x + d sin(theta),  y' = y + d cos(theta),  theta' = theta + dtheta
// Covariance (eq. 4.2-4.4):  P' = Fq P Fq^T + Fv V Fv^T with
//     Fq = [[1, 0, d cos(theta)], [0, 1, -d sin(theta)], [0, 0, 1]]
//     Fv = [[sin(theta), 0], [cos(theta), 0], [0, 1]],  V = diag(var_d, var_theta)
// A camera fix measures the whole pose, H = I; it is compared with the pose the rover had when
// the frame was taken, and the correction is carried to now. That past pose is the current
// estimate less the odometry travelled since: a short history of the raw (never corrected)
// odometry gives it, interpolated between samples.
#pragma once
#include <stdint.h>

#include "noinline.h"

namespace rovernav {
namespace core {

struct PoseFix {
  int16_t x_mm;
  int16_t y_mm;
  int16_t heading_cdeg;
  uint8_t sd_mm;
  uint32_t taken_ms;  ///< when the frame was captured, on the rover's clock
};

enum class FixResult : uint8_t { Initialised, Accepted, Rejected };

class Estimator {
 public:
  /// Forgets everything: no pose until the first fix.
  void reset();
  bool initialised() const { return initialised_; }

  /// Dead reckoning over one step. d_mm: distance travelled (signed), dtheta_rad: heading change,
  /// var_d_mm2 / var_theta_rad2: the step's noise, now_ms: the step's time (for the history).
  void predict(float d_mm, float dtheta_rad, float var_d_mm2, float var_theta_rad2, uint32_t now_ms);

  /// A camera fix. Rejected (and counted) when it is implausibly far from the estimate;
  /// after kMaxRejects rejections in a row the estimate is reset to the fix.
  FixResult update(const PoseFix& fix, uint32_t now_ms);

  // Out of line: a float read from the Uno's global Rover is four four-byte loads at each use.
  ROVERNAV_NOINLINE float x_mm() const { return q_[0]; }
  ROVERNAV_NOINLINE float y_mm() const { return q_[1]; }
  ROVERNAV_NOINLINE float heading_rad() const { return q_[2]; }
  /// Covariance entries (mm^2, mm*rad, rad^2), by kXX ... kTT.
  enum : uint8_t { kXX, kXY, kYY, kXT, kYT, kTT };
  ROVERNAV_NOINLINE float p(uint8_t i) const { return p_[i]; }
  /// Standard deviation along the worst direction of the position error (mm).
  float position_sd_mm() const;
  /// Distance between the last fix and the pose it was compared with (mm): after an outage,
  /// the dead-reckoning error the fix revealed.
  uint16_t last_innovation_mm() const { return last_innovation_mm_; }
#if !defined(__AVR__)
  uint16_t rejected_fixes() const { return rejected_total_; }
#endif

  enum : uint8_t { kHistory = 6, kMaxRejects = 10 };
  enum : uint16_t { kHistoryPeriodMs = 40 };

 private:
  struct Past {
    int16_t xy_mm[2], heading_cdeg;  // raw odometry: x, y
    uint16_t t_ms;                   // low 16 bits of the time
  };
  /// Odometry travelled since t_ms: d = (dx, dy, dtheta). Zero if t_ms is now or later.
  void odometry_since(uint32_t t_ms, uint32_t now_ms, float* d) const;
  /// Moves a pose (x, y, theta) by a step.
  static void advance(float* pose, float dx, float dy, float dth);
  /// The fix z against h (the pose when its frame was taken) by the sequential updates, taken
  /// into the pose and covariance when it passes the gate (else nothing changes).
  enum class Correction : uint8_t { Taken, Degenerate, Gated };
  Correction correct(const float* z, const float* h, float r_pos);
  /// Takes the fix z = (x, y, theta) as the pose, with the fix's noise as its covariance.
  FixResult start_from(const float* z, float r_pos);

  bool initialised_ = false;
  float q_[3] = {};    // the pose: x, y (mm), theta (rad)
  float odo_[3] = {};  // the same by dead reckoning alone, never corrected
  float p_[6] = {};  // xx xy yy xt yt: the position block, then its column with theta, then tt
  uint16_t last_innovation_mm_ = 0;   // saturated
  uint8_t rejects_in_row_ = 0;
#if defined(__AVR__)
  // Nothing on the Uno reads the count of rejected fixes (the native tests do): it keeps neither
  // the counter nor its updates.
  void count_rejected() {}
  void clear_rejected() {}
#else
  void count_rejected() { ++rejected_total_; }
  void clear_rejected() { rejected_total_ = 0; }
  uint16_t rejected_total_ = 0;
#endif
  Past history_[kHistory] = {};
  uint8_t history_next_ = 0;
  uint8_t history_count_ = 0;
  uint16_t history_last_ms_ = 0;   // modulo 65,536: predict() runs every step, 40 ms apart at most
};

}  // namespace core
}  // namespace rovernav
