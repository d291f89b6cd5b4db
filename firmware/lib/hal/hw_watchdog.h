// The AVR hardware watchdog: resets the Uno when the loop stops kicking it.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// WDTCSR (set through avr-libc's wdt_enable, which does the timed WDCE sequence):
//
//   WDE = 1, WDIE = 0      system reset on timeout, no interrupt first
//   WDP3..0 = 0100         250 ms (the 128 kHz oscillator: +-10 % and temperature)
//
// After a watchdog reset the watchdog stays on at its shortest period. A function in .init3
// (before main, before Arduino's init()) records MCUSR and turns it off, so a board flashed
// without the bootloader does not reset forever; optiboot does the same on the Uno.
class HwWatchdog {
 public:
  // 250 ms; board::kWatchdogTimeoutMs names the figure.
  static void enable();
  static void kick();
  static void disable();

  // True when the last reset came from the watchdog, as far as MCUSR still tells. The Uno's
  // optiboot (4.4) clears MCUSR before it starts the sketch after every kind of reset, and an
  // external one reaches the sketch as its own watchdog reset, so behind it this is always
  // false and reset_flags() 0; without a bootloader (an ISP-flashed board, simavr) they tell.
  static bool reset_by_watchdog();
  static uint8_t reset_flags();  // MCUSR as found at start-up
};

}  // namespace hal
}  // namespace rovernav
