// The sonar sweep: stopped, the servo steps from -90 to +90 degrees in 15-degree steps, one
// ping a step. Each step waits for the servo (sweep_step_ms for a 15-degree step: travel and
// settle), fires the sonar, and waits for its result (at most kPingTimeoutMs). A longer move,
// such as the slew to -90 degrees that starts a sweep, adds kSlewMsPerStep for each further
// 15 degrees: an SG90 travels 60 degrees in 0.1 s, and settling is paid once, not per step.
// Nothing waits without a bound: a sonar that never answers costs kPingTimeoutMs a step, not
// the rover.
#pragma once
#include <stdint.h>

namespace rovernav {
namespace core {

class Sweep {
 public:
  enum : int16_t { kFirstCdeg = -9000, kLastCdeg = 9000, kStepCdeg = 1500 };
  enum : uint16_t { kPingTimeoutMs = 60, kSlewMsPerStep = 25 };

  struct Echo {
    bool valid;
    int16_t bearing_cdeg;
    uint16_t range_mm;
  };

  /// Begins a sweep with the servo at servo_cdeg.
  void start(uint32_t now_ms, int16_t servo_cdeg, uint16_t step_ms);
  bool running() const { return running_; }

  /// Advances the sweep. Sets servo_cdeg and fire; returns an echo when a ping's result came.
  /// When the last step is done, running() turns false and the servo is sent back ahead.
  Echo step(uint32_t now_ms, bool sonar_valid, uint16_t sonar_range_mm, int16_t& servo_cdeg, bool& fire);

  uint8_t pings() const { return pings_; }

 private:
  void move_to(uint32_t now_ms, int16_t from, int16_t to);

  bool running_ = false;
  bool waiting_echo_ = false;
  int16_t angle_cdeg_ = 0;
  uint16_t phase_start_ms_ = 0;   // modulo 65,536: a phase lasts sweep_step_ms and a slew (< 6 s) at most
  uint16_t phase_ms_ = 0;
  uint16_t step_ms_ = 0;
  uint8_t pings_ = 0;
};

}  // namespace core
}  // namespace rovernav
