// Where the ultrasonic ranger sits and where an echo lies: the one definition on the rover (the
// host's is rovernav.mapping.sonar_map.sonar_origin / echo_point, the same formula). Headings and
// bearings in radians, 0 = +y, clockwise; lengths in millimetres.
#pragma once

#include <math.h>

namespace rovernav {
namespace core {

struct PointMm {
  float x_mm;
  float y_mm;
};

/// The ranger: `offset_mm` ahead of the rover's centre along its heading.
inline PointMm sonar_origin(float x_mm, float y_mm, float heading_rad, float offset_mm) {
  PointMm p = {x_mm + offset_mm * sinf(heading_rad), y_mm + offset_mm * cosf(heading_rad)};
  return p;
}

/// The echo: on the beam's axis (heading + the servo's bearing), `range_mm` from the ranger.
inline PointMm echo_point(float x_mm, float y_mm, float heading_rad, float bearing_rad, float range_mm,
                          float offset_mm) {
  const PointMm s = sonar_origin(x_mm, y_mm, heading_rad, offset_mm);
  const float axis = heading_rad + bearing_rad;
  PointMm p = {s.x_mm + range_mm * sinf(axis), s.y_mm + range_mm * cosf(axis)};
  return p;
}

}  // namespace core
}  // namespace rovernav
