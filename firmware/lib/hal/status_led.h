// The Uno's built-in LED (pin 13, PB5): lit while something is wrong.
#pragma once

#include <avr/io.h>

#include "board.h"

namespace rovernav {
namespace hal {

static_assert(board::kPinLed == 13, "the LED is PB5 below");

class StatusLed {
 public:
  // Makes the pin an output, LED on or off.
  static void begin(bool on) {
    set(on);
    DDRB = static_cast<uint8_t>(DDRB | _BV(DDB5));
  }

  static void set(bool on) {
    if (on) {
      PORTB = static_cast<uint8_t>(PORTB | _BV(PORTB5));
    } else {
      PORTB = static_cast<uint8_t>(PORTB & ~_BV(PORTB5));
    }
  }
};

}  // namespace hal
}  // namespace rovernav
