// Compile-time checks of board.h against the Arduino Uno variant. No code is generated.
#include <Arduino.h>

#include "board.h"
#include "messages_gen.h"

namespace rovernav {
namespace board {

static_assert(kPinSonarEcho == A0, "HC-SR04 echo is on A0");
static_assert(kPinSonarTrig == A1, "HC-SR04 trigger is on A1");
static_assert(kPinLed == LED_BUILTIN, "status LED is the Uno's built-in LED");
static_assert(kPinStepProbe == 8, "the step probe is D8 = PB0 in main.cpp");
static_assert(kPinConsent == 7, "the consent pin is D7 = PD7 in main.cpp");
static_assert(kPinConsent == kSignConsentPin, "the consent pin is the protocol's [signing].consent_pin");
static_assert(kPinServo == 9, "ServoTimer1 drives OC1A, which is pin 9 on the Uno");
static_assert(kServoPulseMinUs < kServoPulseMaxUs, "servo pulse range is inverted");
static_assert(kServoPulseMaxUs <= 2500, "servo pulse longer than any hobby servo takes");
static_assert(kSonarMinIntervalMs >= 60, "HC-SR04 needs 60 ms between pings");
static_assert(kGyroZToClockwiseSign == 1 || kGyroZToClockwiseSign == -1, "sign is +-1");
static_assert(kServoClockwiseSign == 1 || kServoClockwiseSign == -1, "sign is +-1");
static_assert(F_CPU == 16000000UL, "timer constants assume a 16 MHz Uno");

}  // namespace board
}  // namespace rovernav
