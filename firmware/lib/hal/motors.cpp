#include "motors.h"

#include <avr/io.h>

#include "board.h"

namespace rovernav {
namespace hal {

namespace {

static_assert(board::kPinMotorLeftBack == 3, "left back is OC2B on PD3 below");
static_assert(board::kPinMotorLeftFwd == 5, "left forward is OC0B on PD5 below");
static_assert(board::kPinMotorRightBack == 6, "right back is OC0A on PD6 below");
static_assert(board::kPinMotorRightFwd == 11, "right forward is OC2A on PB3 below");
static_assert(board::kMotorPwmMax == 255, "duty is the 8-bit OCR value");

// Drives one bridge input as analogWrite does: duty 0 and 255 are the port bit held LOW or
// HIGH with the timer disconnected (fast PWM would leave a 1/256 glitch at 255), anything
// between is the timer's non-inverting PWM (COMxx1). The port bit is set before the timer
// lets go of the pin, so the pin never shows a stale level.
__attribute__((always_inline)) inline void write_input(volatile uint8_t& tccra,
                                                       uint8_t com_bit,
                                                       volatile uint8_t& ocr,
                                                       volatile uint8_t& port,
                                                       uint8_t pin_bit, uint8_t duty) {
  if (duty == 0 || duty == 255) {
    if (duty == 0) {
      port = static_cast<uint8_t>(port & ~pin_bit);
    } else {
      port = static_cast<uint8_t>(port | pin_bit);
    }
    tccra = static_cast<uint8_t>(tccra & ~com_bit);
  } else {
    ocr = duty;
    tccra = static_cast<uint8_t>(tccra | com_bit);
  }
}

enum class Input : uint8_t { LeftBack, LeftFwd, RightBack, RightFwd };

void write_duty(Input input, uint8_t duty) {
  switch (input) {
    case Input::LeftBack:
      write_input(TCCR2A, _BV(COM2B1), OCR2B, PORTD, _BV(PORTD3), duty);
      break;
    case Input::LeftFwd:
      write_input(TCCR0A, _BV(COM0B1), OCR0B, PORTD, _BV(PORTD5), duty);
      break;
    case Input::RightBack:
      write_input(TCCR0A, _BV(COM0A1), OCR0A, PORTD, _BV(PORTD6), duty);
      break;
    case Input::RightFwd:
      write_input(TCCR2A, _BV(COM2A1), OCR2A, PORTB, _BV(PORTB3), duty);
      break;
  }
}

__attribute__((noinline)) int16_t clamp_pwm(int16_t pwm) {
  if (pwm > board::kMotorPwmMax) return board::kMotorPwmMax;
  if (pwm < -board::kMotorPwmMax) return static_cast<int16_t>(-board::kMotorPwmMax);
  return pwm;
}

// pwm: -255..255. The input that goes LOW is written first.
void drive_side(Input back, Input fwd, int16_t pwm) {
  if (pwm >= 0) {
    write_duty(back, 0);
    write_duty(fwd, static_cast<uint8_t>(pwm));
  } else {
    write_duty(fwd, 0);
    write_duty(back, static_cast<uint8_t>(-pwm));
  }
}

}  // namespace

void Motors::begin() {
  stop();  // ports low before the pins become outputs
  DDRD = static_cast<uint8_t>(DDRD | _BV(DDD3) | _BV(DDD5) | _BV(DDD6));
  DDRB = static_cast<uint8_t>(DDRB | _BV(DDB3));
}

void Motors::set(int16_t left_pwm, int16_t right_pwm) {
  drive_side(Input::LeftBack, Input::LeftFwd, clamp_pwm(left_pwm));
  drive_side(Input::RightBack, Input::RightFwd, clamp_pwm(right_pwm));
}

void Motors::stop() {
  // A loop over the four inputs, in their order: the four calls written out took more flash.
  for (uint8_t i = 0; i <= static_cast<uint8_t>(Input::RightFwd); ++i) write_duty(static_cast<Input>(i), 0);
}

}  // namespace hal
}  // namespace rovernav
