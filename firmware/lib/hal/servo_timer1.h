// Hobby servo on pin 9 driven by Timer1 hardware PWM (no Servo library, no interrupts).
#pragma once

#include <stdint.h>

#include "board.h"

namespace rovernav {
namespace hal {

// Timer1 registers (ATmega328P datasheet, 16-bit Timer/Counter1):
//
//   register  value                       meaning
//   TCCR1A    COM1A1 | WGM11              OC1A (pin 9) non-inverting, OC1B (pin 10) off
//   TCCR1B    WGM13 | WGM12 | CS11        Fast PWM mode 14 (TOP = ICR1), clk/8 = 0.5 us/tick
//   ICR1      39999                       period 40,000 ticks = 20 ms (50 Hz)
//   OCR1A     pulse_us * 2                high time; double-buffered, loaded at BOTTOM,
//                                         so a new angle never produces a runt pulse
//
// Angles are centidegrees relative to straight ahead, clockwise positive seen from above
// (the rover's heading convention). Servo angle = 90 deg + trim + sign * angle, clamped to
// the servo's 0..180 deg travel; 0..180 deg maps linearly onto kServoPulseMinUs..MaxUs.
// Owning Timer1 means analogWrite on pins 9 and 10 no longer works.
class ServoTimer1 {
 public:
  explicit constexpr ServoTimer1(int16_t centre_trim_cdeg = board::kServoCentreTrimCdeg)
      : trim_offset_cdeg_(static_cast<int16_t>(centre_trim_cdeg - board::kServoCentreTrimCdeg)) {}

  // Takes over Timer1 and starts pulses at angle_cdeg.
  void begin(int16_t angle_cdeg = 0);

  // Returns the angle actually commanded, which differs from angle_cdeg when the servo's
  // travel ends first.
  int16_t write_cdeg(int16_t angle_cdeg);

  // Changes the trim and re-sends the current angle.
  void set_trim_cdeg(int16_t centre_trim_cdeg);

  // Stops the pulses: the servo goes limp and draws less current. begin() restarts them.
  void off();

  int16_t angle_cdeg() const { return angle_cdeg_; }
  uint16_t pulse_us() const { return pulse_us_; }
  int16_t trim_cdeg() const { return static_cast<int16_t>(board::kServoCentreTrimCdeg + trim_offset_cdeg_); }

 private:
  // The trim less the board's: a servo with the board's trim is all zeros, so the shell's global
  // one lies in .bss. With no initialised data at all the image needs no start-up copy loop.
  int16_t trim_offset_cdeg_;
  int16_t angle_cdeg_ = 0;
  uint16_t pulse_us_ = 0;
};

}  // namespace hal
}  // namespace rovernav
