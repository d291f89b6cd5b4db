// Two DC motors through an L298N-style dual H-bridge.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// Pin pattern per side (IN_back, IN_fwd; board.h names the pins):
//
//   command      IN_back        IN_fwd
//   forward  n   LOW            PWM n/255
//   backward n   PWM n/255      LOW
//   stop         LOW            LOW        (the L298N lets the motor coast)
//
// The pin that goes LOW is always written before the pin that gets PWM, so a side never has
// both inputs high. PWM is analogWrite on Timer0 (pins 5, 6) and Timer2 (pins 3, 11), about
// 980 Hz and 490 Hz; the timers are left as the Arduino core sets them.
class Motors {
 public:
  void begin();

  // left_pwm, right_pwm: -255..255, positive drives forward; values beyond are clamped.
  void set(int16_t left_pwm, int16_t right_pwm);
  void stop();

  int16_t left_pwm() const { return left_pwm_; }
  int16_t right_pwm() const { return right_pwm_; }

 private:
  static void drive_side(uint8_t back_pin, uint8_t fwd_pin, int16_t pwm);

  int16_t left_pwm_ = 0;
  int16_t right_pwm_ = 0;
};

}  // namespace hal
}  // namespace rovernav
