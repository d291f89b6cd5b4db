#include "motors.h"

#include <Arduino.h>

#include "board.h"

namespace rovernav {
namespace hal {

namespace {

int16_t clamp_pwm(int16_t pwm) {
  if (pwm > board::kMotorPwmMax) return board::kMotorPwmMax;
  if (pwm < -board::kMotorPwmMax) return static_cast<int16_t>(-board::kMotorPwmMax);
  return pwm;
}

}  // namespace

void Motors::begin() {
  pinMode(board::kPinMotorLeftBack, OUTPUT);
  pinMode(board::kPinMotorLeftFwd, OUTPUT);
  pinMode(board::kPinMotorRightBack, OUTPUT);
  pinMode(board::kPinMotorRightFwd, OUTPUT);
  stop();
}

void Motors::set(int16_t left_pwm, int16_t right_pwm) {
  left_pwm_ = clamp_pwm(left_pwm);
  right_pwm_ = clamp_pwm(right_pwm);
  drive_side(board::kPinMotorLeftBack, board::kPinMotorLeftFwd, left_pwm_);
  drive_side(board::kPinMotorRightBack, board::kPinMotorRightFwd, right_pwm_);
}

void Motors::stop() {
  left_pwm_ = 0;
  right_pwm_ = 0;
  digitalWrite(board::kPinMotorLeftBack, LOW);
  digitalWrite(board::kPinMotorLeftFwd, LOW);
  digitalWrite(board::kPinMotorRightBack, LOW);
  digitalWrite(board::kPinMotorRightFwd, LOW);
}

void Motors::drive_side(uint8_t back_pin, uint8_t fwd_pin, int16_t pwm) {
  // analogWrite(pin, 0) also turns the timer output off and drives the pin low.
  if (pwm >= 0) {
    digitalWrite(back_pin, LOW);
    analogWrite(fwd_pin, pwm);
  } else {
    digitalWrite(fwd_pin, LOW);
    analogWrite(back_pin, -pwm);
  }
}

}  // namespace hal
}  // namespace rovernav
