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
// both inputs high. PWM comes from the timers' output-compare channels, written directly:
//
//   pin  port  channel  timer mode (as the Arduino core's init() leaves it)
//   3    PD3   OC2B     Timer2 phase-correct PWM, clk/64: 490 Hz
//   5    PD5   OC0B     Timer0 fast PWM, clk/64: 977 Hz (Timer0 also counts millis())
//   6    PD6   OC0A     Timer0 fast PWM, clk/64: 977 Hz
//   11   PB3   OC2A     Timer2 phase-correct PWM, clk/64: 490 Hz
//
// Duty 0 and 255 hold the pin LOW and HIGH with the timer disconnected, as analogWrite does;
// anything between sets OCRxx and connects the channel (COMxx1, non-inverting).
class Motors {
 public:
  void begin();

  // left_pwm, right_pwm: -255..255, positive drives forward; values beyond are clamped.
  void set(int16_t left_pwm, int16_t right_pwm);
  void stop();
};

}  // namespace hal
}  // namespace rovernav
