// The estimate and dead reckoning: the pose, the distance driven without fixes, the speed
// model's calibration.
#pragma once
#include <stdint.h>

#include "estimator.h"

namespace rovernav {
namespace core {

/// Written by odometry.cpp. link_in.cpp hands a FIX to the estimator (est.update) and restarts
/// dr_distance_mm on it, failsafe.cpp restarts it when dead reckoning begins; rover.cpp's begin()
/// sets speed_scale and enter() starts a drive's clock (drive_since_ms, calib_anchor).
struct OdometryState {
  Estimator est;
  float dr_distance_mm = 0.0f;
  float speed_scale = 0.0f;              ///< the speed model's calibration (1 from begin())
  bool calib_anchor = false;
  uint32_t drive_since_ms = 0;
  int16_t calib_x_mm = 0, calib_y_mm = 0;   ///< the fix calibration measures from
  float calib_model_mm = 0.0f;           ///< the model's distance since that fix
};

}  // namespace core
}  // namespace rovernav
