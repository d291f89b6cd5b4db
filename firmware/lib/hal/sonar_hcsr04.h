// HC-SR04 ultrasonic ranger: one bounded ping at a time, never more often than every 60 ms.
#pragma once

#include <stdint.h>

#include "board.h"

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
// ping() blocks, but for at most kRiseTimeoutUs (echo never started: sensor missing) plus
// the echo time of max_range_mm (no target that close): about 10.8 ms at 1 m. It returns as
// soon as the echo passes the range limit and does not wait for the sensor's own timeout.
// Timing uses micros() (4 us, 0.7 mm resolution) with interrupts left on, so the serial and
// millis() interrupts delay it by microseconds, not by lost bytes.
//
// Pins by register (board.h names them): trigger A1 = PC1, echo A0 = PC0.

enum class SonarResult : uint8_t {
  Ok,        // range_mm holds a new range
  NoEcho,    // nothing within max_range_mm
  NoSensor,  // ECHO never rose after the trigger: unplugged or dead
  TooSoon,   // less than kSonarMinIntervalMs since the previous ping; nothing was sent
  Busy,      // ECHO still high from the previous ping; nothing was sent
};

class SonarHcsr04 {
 public:
  static constexpr uint32_t kRiseTimeoutUs = 5000;

  explicit constexpr SonarHcsr04(uint16_t max_range_mm = board::kSonarMaxRangeMm)
      : max_range_mm_(max_range_mm) {}

  // Trigger (A1) an output held low, echo (A0) an input without pull-up.
  void begin();

  // now_ms: millis() of the caller's tick. range_mm is written only when Ok is returned.
  // NoSensor also when begin() has not been called.
  SonarResult ping(uint32_t now_ms, uint16_t& range_mm);

  // True when ping() would send a trigger at now_ms (interval elapsed; ECHO is not checked).
  bool interval_elapsed(uint32_t now_ms) const;

  uint16_t max_range_mm() const { return max_range_mm_; }

 private:
  uint16_t max_range_mm_;
  uint32_t last_ping_ms_ = 0;
  bool pinged_ = false;
};

}  // namespace hal
}  // namespace rovernav
