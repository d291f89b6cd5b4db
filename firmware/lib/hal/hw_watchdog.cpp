#include "hw_watchdog.h"

#include <avr/io.h>
#include <avr/wdt.h>

#include "board.h"

// Runs from .init3, before static constructors and main(); naked and without a prologue, so
// it may only touch I/O registers and a .noinit byte.
extern "C" void rovernav_watchdog_early_off(void) __attribute__((naked, used, section(".init3")));

namespace {
uint8_t g_reset_flags __attribute__((section(".noinit")));
}

extern "C" void rovernav_watchdog_early_off(void) {
  g_reset_flags = MCUSR;
  MCUSR = 0;
  wdt_disable();
}

namespace rovernav {
namespace hal {

static_assert(board::kWatchdogTimeoutMs == 250, "enable() uses WDTO_250MS");

void HwWatchdog::enable() { wdt_enable(WDTO_250MS); }

void HwWatchdog::kick() { wdt_reset(); }

void HwWatchdog::disable() { wdt_disable(); }

bool HwWatchdog::reset_by_watchdog() { return (g_reset_flags & _BV(WDRF)) != 0; }

uint8_t HwWatchdog::reset_flags() { return g_reset_flags; }

}  // namespace hal
}  // namespace rovernav
