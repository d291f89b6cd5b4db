#include "sweep.h"

#include "noinline.h"

namespace rovernav {
namespace core {

ROVERNAV_NOINLINE void Sweep::move_to(uint32_t now_ms, int16_t from, int16_t to) {
  // In 16 bits: a move is at most 180 degrees (12 steps), a phase sweep_step_ms (<= 5 s) and
  // the slew.
  const uint16_t moved = static_cast<uint16_t>(to > from ? to - from : from - to);
  const uint8_t steps = static_cast<uint8_t>((moved + kStepCdeg - 1) / kStepCdeg);
  angle_cdeg_ = to;
  phase_start_ms_ = static_cast<uint16_t>(now_ms);
  const uint16_t slew_ms = step_ms_ < kSlewMsPerStep ? step_ms_ : static_cast<uint16_t>(kSlewMsPerStep);
  const uint16_t wait_ms = static_cast<uint16_t>(step_ms_ + (steps > 1 ? (steps - 1) * slew_ms : 0));
  // The HC-SR04 needs about 60 ms between pings for the last echo to die away.
  phase_ms_ = wait_ms < kPingTimeoutMs ? static_cast<uint16_t>(kPingTimeoutMs) : wait_ms;
  waiting_echo_ = false;
}

void Sweep::start(uint32_t now_ms, int16_t servo_cdeg, uint16_t step_ms) {
  running_ = true;
  pings_ = 0;
  step_ms_ = step_ms;
  move_to(now_ms, servo_cdeg, kFirstCdeg);
}

Sweep::Echo Sweep::step(uint32_t now_ms, bool sonar_valid, uint16_t sonar_range_mm, int16_t& servo_cdeg, bool& fire) {
  Echo echo = {false, 0, 0};
  fire = false;
  if (!running_) return echo;
  servo_cdeg = angle_cdeg_;
  const uint16_t elapsed = static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - phase_start_ms_);
  if (!waiting_echo_) {
    if (elapsed >= phase_ms_) {
      fire = true;
      waiting_echo_ = true;
      phase_start_ms_ = static_cast<uint16_t>(now_ms);
      ++pings_;
    }
    return echo;
  }
  const bool timed_out = elapsed >= kPingTimeoutMs;
  if (!sonar_valid && !timed_out) return echo;
  if (sonar_valid) {
    echo.valid = true;
    echo.bearing_cdeg = angle_cdeg_;
    echo.range_mm = sonar_range_mm;
  }
  if (angle_cdeg_ >= kLastCdeg) {
    running_ = false;
    waiting_echo_ = false;
    angle_cdeg_ = 0;
    servo_cdeg = 0;
  } else {
    move_to(now_ms, angle_cdeg_, static_cast<int16_t>(angle_cdeg_ + kStepCdeg));
  }
  return echo;
}

}  // namespace core
}  // namespace rovernav
