#include "sonar_hcsr04.h"

#include <Arduino.h>

namespace rovernav {
namespace hal {

namespace {

// Round trip: width_us = 2 * range_mm / (c mm/ms) * 1000.
uint32_t echo_us_for_range(uint16_t range_mm) {
  return (static_cast<uint32_t>(range_mm) * 2000UL + board::kSpeedOfSoundMmPerMs - 1) /
         board::kSpeedOfSoundMmPerMs;
}

uint16_t range_mm_for_echo(uint32_t width_us) {
  return static_cast<uint16_t>((width_us * board::kSpeedOfSoundMmPerMs + 1000UL) / 2000UL);
}

}  // namespace

SonarHcsr04::SonarHcsr04(uint16_t max_range_mm)
    : max_range_mm_(max_range_mm), max_echo_us_(echo_us_for_range(max_range_mm)) {}

void SonarHcsr04::begin() {
  pinMode(board::kPinSonarTrig, OUTPUT);
  digitalWrite(board::kPinSonarTrig, LOW);
  pinMode(board::kPinSonarEcho, INPUT);
  echo_in_ = portInputRegister(digitalPinToPort(board::kPinSonarEcho));
  echo_mask_ = digitalPinToBitMask(board::kPinSonarEcho);
}

bool SonarHcsr04::interval_elapsed(uint32_t now_ms) const {
  return !pinged_ || now_ms - last_ping_ms_ >= board::kSonarMinIntervalMs;
}

SonarResult SonarHcsr04::ping(uint32_t now_ms, uint16_t& range_mm) {
  if (echo_in_ == nullptr) return SonarResult::NoSensor;  // begin() was not called
  if (!interval_elapsed(now_ms)) return SonarResult::TooSoon;
  if (echo_high()) return SonarResult::Busy;

  last_ping_ms_ = now_ms;
  pinged_ = true;
  digitalWrite(board::kPinSonarTrig, HIGH);
  delayMicroseconds(10);
  digitalWrite(board::kPinSonarTrig, LOW);

  const uint32_t trigger_us = micros();
  while (!echo_high()) {
    if (micros() - trigger_us > kRiseTimeoutUs) return SonarResult::NoSensor;
  }
  const uint32_t rise_us = micros();
  uint32_t width_us = 0;
  while (echo_high()) {
    width_us = micros() - rise_us;
    if (width_us > max_echo_us_) return SonarResult::NoEcho;
  }
  width_us = micros() - rise_us;
  range_mm = range_mm_for_echo(width_us);
  if (range_mm > max_range_mm_) return SonarResult::NoEcho;
  return SonarResult::Ok;
}

}  // namespace hal
}  // namespace rovernav
