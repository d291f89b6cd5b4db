// Pins and board constants of the rover: the one place they are written down.
//
// The wiring is the seed rover's (Pont 2019, Appendix B): an Arduino Uno, an L298N-style
// dual H-bridge, a hobby servo carrying an HC-SR04, an MPU-6050 on I2C (A4/A5) and a 3DR
// radio on the hardware serial port. This header has no Arduino include so that anything
// may read the numbers; board_check.cpp checks them against the Arduino variant.
#pragma once

#include <stdint.h>

#include "vehicle_gen.h"   // the vehicle's facts (protocol/vehicle.toml): the baud rate, the sonar's range

namespace rovernav {
namespace board {

// --- Motors (L298N inputs). Each side has one PWM pin per direction; the other is held low.
// Pins 5 and 6 are Timer0 PWM (Timer0 also runs millis(): never reconfigure it), pins 3 and
// 11 are Timer2 PWM (so tone() must not be used).
constexpr uint8_t kPinMotorLeftBack = 3;    // IN1, OC2B
constexpr uint8_t kPinMotorLeftFwd = 5;     // IN2, OC0B
constexpr uint8_t kPinMotorRightBack = 6;   // IN3, OC0A
constexpr uint8_t kPinMotorRightFwd = 11;   // IN4, OC2A
constexpr int16_t kMotorPwmMax = 255;

// --- Sonar servo on OC1A. Timer1 belongs to ServoTimer1, so analogWrite on 9 and 10 is gone.
constexpr uint8_t kPinServo = 9;
constexpr uint16_t kServoPulseMinUs = 544;    // servo at 0 degrees
constexpr uint16_t kServoPulseMaxUs = 2400;   // servo at 180 degrees
// The seed's sonar looked straight ahead at a servo angle of 78 degrees, not 90.
constexpr int16_t kServoCentreTrimCdeg = -1200;
// +1: a larger servo angle turns the sonar clockwise seen from above. Check on the rover:
// command +3000 and the sonar must turn to the right.
constexpr int8_t kServoClockwiseSign = 1;

// --- HC-SR04. A0 and A1 are digital pins 14 and 15 on the Uno.
constexpr uint8_t kPinSonarEcho = 14;   // A0
constexpr uint8_t kPinSonarTrig = 15;   // A1
constexpr uint16_t kSonarMinIntervalMs = 60;    // datasheet: >= 60 ms between pings
// (Its range, past which an echo is NoEcho, is a vehicle fact: kSonarMaxRangeMm, protocol/vehicle.toml.)
constexpr uint16_t kSpeedOfSoundMmPerMs = 343;  // dry air at 20 C

// --- MPU-6050 on the hardware I2C pins (A4 SDA, A5 SCL). Its INT line is wired to pin 2
// but the driver polls; nothing waits on the pin.
constexpr uint8_t kPinGyroInt = 2;
constexpr uint8_t kMpuAddress = 0x68;           // AD0 low
constexpr uint32_t kI2cClockHz = 400000;
// Rover heading is clockwise-positive seen from above (seed convention, DESIGN.md).
// The MPU-6050 is mounted with its Z axis up, so its Z rate is counter-clockwise-positive:
// heading rate = kGyroZToClockwiseSign * gyro Z rate. This is the only place the sign lives.
constexpr int8_t kGyroZToClockwiseSign = -1;
constexpr uint16_t kGyroCalSamples = 100;       // at the 100 Hz sample rate: one second
constexpr uint16_t kGyroCalMaxMs = 2000;        // give up calibrating after this long
constexpr int32_t kGyroCalMaxSpreadMdps = 3000; // a wider spread means the rover moved

// --- Serial link (3DR radio), 8N1, at the vehicle's baud rate (protocol/vehicle.toml).
constexpr uint32_t kSerialBaud = kLinkBaud;

// --- Status LED.
constexpr uint8_t kPinLed = 13;

// --- Step probe: high while a 10 ms step works (a scope on D8, or the AVR simulator, times it).
constexpr uint8_t kPinStepProbe = 8;   // PB0

// --- Consent pin: a jumper from D7 to GND while the rover resets is its owner's consent to a new
// link key (or an erase) sent unsigned ([signing].consent_pin; link_in.cpp's on_provision). Read
// once at start-up with the pull-up on; take the jumper off after provisioning. Free in the seed's
// wiring (as are 4, 10, 12, A2 and A3).
constexpr uint8_t kPinConsent = 7;     // PD7

// --- Watchdog: the loop must kick it at least this often.
constexpr uint16_t kWatchdogTimeoutMs = 250;

// --- EEPROM layout.
constexpr uint16_t kEepromBootCounterAddr = 0;   // uint16_t, little-endian
constexpr uint16_t kEepromLinkAddr = 16;         // the link key and signing counters (link_store.h), 49 bytes

}  // namespace board
}  // namespace rovernav
