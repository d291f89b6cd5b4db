#include "sonar_hcsr04.h"

#include <Arduino.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

namespace rovernav {
namespace hal {

namespace {

static_assert(board::kPinSonarEcho == 14, "echo is A0 = PC0 = PCINT8 below");
static_assert(board::kPinSonarTrig == 15, "trigger is A1 = PC1 below");
constexpr uint8_t kEchoBit = _BV(PINC0);
constexpr uint8_t kTrigBit = _BV(PORTC1);

// Written by the pin-change interrupt, read by poll() with interrupts off.
volatile uint16_t g_rise_us = 0;   // low 16 bits of micros()
volatile uint16_t g_fall_us = 0;
volatile uint8_t g_edges = 0;   // 0 armed, 1 rose, 2 fell; the ISR ignores edges past 2

bool echo_high() { return (PINC & kEchoBit) != 0; }

// begin() is the only thing that makes the trigger pin an output.
bool begun() { return (DDRC & kTrigBit) != 0; }

// Round trip: width_us = 2 * range_mm / (c mm/ms) * 1000.
uint16_t echo_us_for_range(uint16_t range_mm) {
  return static_cast<uint16_t>((static_cast<uint32_t>(range_mm) * 2000UL + board::kSpeedOfSoundMmPerMs - 1) /
                               board::kSpeedOfSoundMmPerMs);
}

uint16_t range_mm_for_echo(uint16_t width_us) {
  return static_cast<uint16_t>((static_cast<uint32_t>(width_us) * board::kSpeedOfSoundMmPerMs + 1000UL) / 2000UL);
}

}  // namespace

}  // namespace hal
}  // namespace rovernav

// PC0 is the only pin of port C with its change interrupt enabled: every call is an ECHO edge.
ISR(PCINT1_vect) {
  using namespace rovernav::hal;
  const uint16_t t = static_cast<uint16_t>(micros());
  const uint8_t edges = g_edges;
  if (edges == 0 && echo_high()) {
    g_rise_us = t;
    g_edges = 1;
  } else if (edges == 1 && !echo_high()) {
    g_fall_us = t;
    g_edges = 2;
  }
}

namespace rovernav {
namespace hal {

void SonarHcsr04::begin() {
  PORTC = static_cast<uint8_t>(PORTC & ~(kTrigBit | kEchoBit));  // trigger low, no pull-up
  DDRC = static_cast<uint8_t>((DDRC | kTrigBit) & ~kEchoBit);
  g_edges = 2;   // nothing to time until a trigger arms it
  PCMSK1 = static_cast<uint8_t>(PCMSK1 | _BV(PCINT8));
  PCIFR = _BV(PCIF1);   // forget an edge from before
  PCICR = static_cast<uint8_t>(PCICR | _BV(PCIE1));
}

bool SonarHcsr04::interval_elapsed(uint32_t now_ms) const {
  return !pinged_ || static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - last_ping_ms_) >= board::kSonarMinIntervalMs;
}

SonarResult SonarHcsr04::trigger(uint32_t now_ms) {
  if (!begun()) return SonarResult::NoSensor;
  if (!interval_elapsed(now_ms)) return SonarResult::TooSoon;
  if (echo_high()) return SonarResult::Busy;
  last_ping_ms_ = static_cast<uint16_t>(now_ms);
  pinged_ = true;
  waiting_ = true;
  g_edges = 0;   // armed: an 8-bit store, atomic
  PORTC = static_cast<uint8_t>(PORTC | kTrigBit);
  delayMicroseconds(10);
  PORTC = static_cast<uint8_t>(PORTC & ~kTrigBit);
  trigger_us_ = static_cast<uint16_t>(micros());
  return SonarResult::Pending;
}

SonarResult SonarHcsr04::poll(uint32_t now_us, uint16_t& range_mm) {
  if (!waiting_) return SonarResult::Idle;
  uint8_t edges;
  uint16_t rise_us, fall_us;
  const uint16_t now16 = static_cast<uint16_t>(now_us);
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    edges = g_edges;
    rise_us = g_rise_us;
    fall_us = g_fall_us;
  }
  if (edges == 0) {
    if (static_cast<uint16_t>(now16 - trigger_us_) <= kRiseTimeoutUs) return SonarResult::Pending;
    waiting_ = false;
    g_edges = 2;
    return SonarResult::NoSensor;
  }
  const uint16_t max_echo_us = echo_us_for_range(kMaxRangeMm);
  const uint16_t width_us = static_cast<uint16_t>(edges == 2 ? fall_us - rise_us : now16 - rise_us);
  if (width_us > max_echo_us) {   // longer than max_range_mm needs: no need to wait for the fall
    waiting_ = false;
    g_edges = 2;
    return SonarResult::NoEcho;
  }
  if (edges == 1) return SonarResult::Pending;
  waiting_ = false;
  range_mm = range_mm_for_echo(width_us);
  return range_mm > kMaxRangeMm ? SonarResult::NoEcho : SonarResult::Ok;
}

}  // namespace hal
}  // namespace rovernav
