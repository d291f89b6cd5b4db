#include "servo_timer1.h"

#include <avr/io.h>
#include <util/atomic.h>

namespace rovernav {
namespace hal {

namespace {

constexpr uint16_t kTicksPerUs = 2;   // 16 MHz / 8
constexpr uint16_t kPeriodUs = 20000;
constexpr int32_t kServoTravelCdeg = 18000;
constexpr int32_t kServoMidCdeg = 9000;

static_assert(board::kPinServo == 9, "the servo is OC1A on PB1 below");

static_assert(static_cast<uint32_t>(kPeriodUs) * kTicksPerUs - 1 <= 0xFFFF,
              "20 ms period must fit ICR1");

void load_ocr1a(uint16_t ticks) {
  // 16-bit timer registers go through the shared TEMP byte: no interrupt in between.
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { OCR1A = ticks; }
}

}  // namespace

void ServoTimer1::begin(int16_t angle_cdeg) {
  PORTB = static_cast<uint8_t>(PORTB & ~_BV(PORTB1));  // low until the timer takes the pin
  DDRB = static_cast<uint8_t>(DDRB | _BV(DDB1));
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    TCCR1B = 0;  // stop the timer while it is set up
    TCCR1A = 0;
    TCNT1 = 0;
    ICR1 = kPeriodUs * kTicksPerUs - 1;
  }
  write_cdeg(angle_cdeg);
  TCCR1A = _BV(COM1A1) | _BV(WGM11);
  TCCR1B = _BV(WGM13) | _BV(WGM12) | _BV(CS11);
}

int16_t ServoTimer1::write_cdeg(int16_t angle_cdeg) {
  int32_t servo_cdeg = kServoMidCdeg + trim_cdeg() +
                       static_cast<int32_t>(board::kServoClockwiseSign) * angle_cdeg;
  if (servo_cdeg < 0) servo_cdeg = 0;
  if (servo_cdeg > kServoTravelCdeg) servo_cdeg = kServoTravelCdeg;

  angle_cdeg_ = static_cast<int16_t>(board::kServoClockwiseSign *
                                     (servo_cdeg - kServoMidCdeg - trim_cdeg()));
  const int32_t span_us = board::kServoPulseMaxUs - board::kServoPulseMinUs;
  pulse_us_ = static_cast<uint16_t>(board::kServoPulseMinUs +
                                    (servo_cdeg * span_us + kServoTravelCdeg / 2) /
                                        kServoTravelCdeg);
  load_ocr1a(static_cast<uint16_t>(pulse_us_ * kTicksPerUs));
  return angle_cdeg_;
}

void ServoTimer1::set_trim_cdeg(int16_t centre_trim_cdeg) {
  trim_offset_cdeg_ = static_cast<int16_t>(centre_trim_cdeg - board::kServoCentreTrimCdeg);
  write_cdeg(angle_cdeg_);
}

void ServoTimer1::off() {
  TCCR1A = static_cast<uint8_t>(TCCR1A & ~(_BV(COM1A1) | _BV(COM1A0)));
  PORTB = static_cast<uint8_t>(PORTB & ~_BV(PORTB1));
}

}  // namespace hal
}  // namespace rovernav
