// HC-SR04 ultrasonic ranger, interrupt-driven: a step triggers a ping and returns; the echo is
// timed by a pin-change interrupt on its pin; a later step collects the range. Nothing waits.
#pragma once

#include <stdint.h>

#include "board.h"
#include "messages_gen.h"

namespace rovernav {
namespace hal {

// Wire format (HC-SR04 datasheet):
//
//   TRIG  __/ >= 10 us \_____________________________________________
//   ECHO  ______ ~0.5 ms ______/ width = 2 * range / c \_____________
//
//   range_mm = width_us * 343 / 2000      (c = 343 m/s; 1 m is about 5,831 us)
//   no target: ECHO stays high ~38 ms (some clones longer) and then falls
//   next trigger: >= 60 ms after the previous one, and only once ECHO is low
//
// trigger() holds TRIG high for 10 us (the only wait, and a fixed one) and returns. The
// pin-change interrupt of ECHO (PCINT8 on PC0) stamps its rise and its fall with micros()
// (4 us, 0.7 mm). poll() gives the range once the echo has fallen, NoEcho as soon as the echo
// has lasted longer than max_range_mm needs (not the sensor's own 38 ms), NoSensor if it never
// rose within kRiseTimeoutUs. The ISR takes about 6 us; poll() about 20 us.
//
// Pins by register (board.h names them): trigger A1 = PC1, echo A0 = PC0.

enum class SonarResult : uint8_t {
  Ok,        // range_mm holds a new range
  NoEcho,    // nothing within max_range_mm
  NoSensor,  // ECHO never rose after the trigger: unplugged or dead (or begin() not called)
  TooSoon,   // less than kSonarMinIntervalMs since the previous ping; nothing was sent
  Busy,      // ECHO still high from the previous ping; nothing was sent
  Pending,   // trigger(): the ping is out; poll(): its result is still to come
  Idle,      // poll(): no ping is out
};

// Times are kept as the low 16 bits of millis() and micros() (RAM is the Uno's scarcest
// resource): every interval measured here is far shorter than 65 ms or 65 s.
class SonarHcsr04 {
 public:
  static constexpr uint16_t kRiseTimeoutUs = 5000;
  static constexpr uint16_t kMaxRangeMm = kSonarMaxRangeMm;   // protocol/vehicle.toml

  // Trigger (A1) an output held low, echo (A0) an input without pull-up, its interrupt on.
  void begin();

  // Sends a ping (Pending), or says why not (NoSensor, TooSoon, Busy). now_ms: millis().
  SonarResult trigger(uint32_t now_ms);

  // The outstanding ping's result: Pending while it is under way, then once Ok (range_mm
  // written), NoEcho or NoSensor; Idle when no ping is out. now_us: micros().
  SonarResult poll(uint32_t now_us, uint16_t& range_mm);

  // True when trigger() would send at now_ms (interval elapsed; ECHO is not checked).
  bool interval_elapsed(uint32_t now_ms) const;

  uint16_t max_range_mm() const { return kMaxRangeMm; }

 private:
  uint16_t last_ping_ms_ = 0;
  uint16_t trigger_us_ = 0;
  bool pinged_ : 1;
  bool waiting_ : 1;

 public:
  constexpr SonarHcsr04() : pinged_(false), waiting_(false) {}
};

}  // namespace hal
}  // namespace rovernav
