#include "sonar_hcsr04.h"

#include <Arduino.h>
#include <avr/io.h>

namespace rovernav {
namespace hal {

namespace {

static_assert(board::kPinSonarEcho == 14, "echo is A0 = PC0 below");
static_assert(board::kPinSonarTrig == 15, "trigger is A1 = PC1 below");
constexpr uint8_t kEchoBit = _BV(PINC0);
constexpr uint8_t kTrigBit = _BV(PORTC1);

bool echo_high() { return (PINC & kEchoBit) != 0; }

// begin() is the only thing that makes the trigger pin an output.
bool begun() { return (DDRC & kTrigBit) != 0; }

// Round trip: width_us = 2 * range_mm / (c mm/ms) * 1000.
uint32_t echo_us_for_range(uint16_t range_mm) {
  return (static_cast<uint32_t>(range_mm) * 2000UL + board::kSpeedOfSoundMmPerMs - 1) /
         board::kSpeedOfSoundMmPerMs;
}

uint16_t range_mm_for_echo(uint32_t width_us) {
  return static_cast<uint16_t>((width_us * board::kSpeedOfSoundMmPerMs + 1000UL) / 2000UL);
}

}  // namespace

void SonarHcsr04::begin() {
  PORTC = static_cast<uint8_t>(PORTC & ~(kTrigBit | kEchoBit));  // trigger low, no pull-up
  DDRC = static_cast<uint8_t>((DDRC | kTrigBit) & ~kEchoBit);
}

bool SonarHcsr04::interval_elapsed(uint32_t now_ms) const {
  return !pinged_ || now_ms - last_ping_ms_ >= board::kSonarMinIntervalMs;
}

SonarResult SonarHcsr04::ping(uint32_t now_ms, uint16_t& range_mm) {
  if (!begun()) return SonarResult::NoSensor;
  if (!interval_elapsed(now_ms)) return SonarResult::TooSoon;
  if (echo_high()) return SonarResult::Busy;

  // Worked out before the trigger: a 32-bit division inside the timing would skew it.
  const uint32_t max_echo_us = echo_us_for_range(max_range_mm_);
  last_ping_ms_ = now_ms;
  pinged_ = true;
  PORTC = static_cast<uint8_t>(PORTC | kTrigBit);
  delayMicroseconds(10);
  PORTC = static_cast<uint8_t>(PORTC & ~kTrigBit);

  const uint32_t trigger_us = micros();
  while (!echo_high()) {
    if (micros() - trigger_us > kRiseTimeoutUs) return SonarResult::NoSensor;
  }
  const uint32_t rise_us = micros();
  uint32_t width_us = 0;
  while (echo_high()) {
    width_us = micros() - rise_us;
    if (width_us > max_echo_us) return SonarResult::NoEcho;
  }
  width_us = micros() - rise_us;
  range_mm = range_mm_for_echo(width_us);
  if (range_mm > max_range_mm_) return SonarResult::NoEcho;
  return SonarResult::Ok;
}

}  // namespace hal
}  // namespace rovernav
