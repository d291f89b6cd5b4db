// The estimate and dead reckoning: the pose, the distance driven without fixes, the speed
// model's calibration.
#pragma once
#include <stdint.h>

#include "estimator.h"

namespace rovernav {
namespace core {

/// Written by odometry.cpp. The others through the functions below: link_in.cpp restarts the
/// distance dead reckoned on a fix taken and failsafe.cpp when dead reckoning begins
/// (restart_dr); rover.cpp's begin() sets the speed model's scale (begin) and its enter() starts a
/// drive's clock (drive_starts). link_in.cpp's on_fix() hands a FIX to the estimator (est.update,
/// the Estimator's own interface).
struct OdometryState {
  Estimator est;
  float dr_distance_mm = 0.0f;
  float speed_scale = 0.0f;              ///< the speed model's calibration (1 from begin())
  bool calib_anchor = false;
  uint32_t drive_since_ms = 0;
  int16_t calib_x_mm = 0, calib_y_mm = 0;   ///< the fix calibration measures from
  float calib_model_mm = 0.0f;           ///< the model's distance since that fix

  void begin() { speed_scale = 1.0f; }
  void restart_dr() { dr_distance_mm = 0.0f; }
  void drive_starts(uint32_t now_ms) {
    calib_anchor = false;
    drive_since_ms = now_ms;
  }
};

}  // namespace core
}  // namespace rovernav
