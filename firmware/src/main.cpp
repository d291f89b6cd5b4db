// The Arduino shell of the rover: reads the sensors, steps the autonomy core every 10 ms, and
// applies what it asks for to the pins. Everything that touches hardware is here or in lib/hal;
// every decision is in lib/core, which the native tests and the simulator run unchanged.
//
// Nothing here waits without a bound: the gyro read and the sonar ping have time limits in
// their drivers, serial writes never exceed the room in the TX buffer, and the watchdog resets
// the board if a loop ever takes longer than 250 ms.
#include <Arduino.h>

#include "board.h"
#include "boot_counter.h"
#include "hw_watchdog.h"
#include "link_serial.h"
#include "motors.h"
#include "mpu6050.h"
#include "rover.h"
#include "servo_timer1.h"
#include "sonar_hcsr04.h"
#include "status_led.h"

namespace {

using namespace rovernav;

constexpr uint8_t kStepMs = 10;  // the core runs at 100 Hz
constexpr uint8_t kRxChunk = 64;

core::Rover rover;
hal::Motors motors;
hal::ServoTimer1 servo;
hal::SonarHcsr04 sonar;
hal::Mpu6050 gyro;
hal::LinkSerial serial_link;

hal::MpuResult gyro_state = hal::MpuResult::NotStarted;
uint32_t last_step_ms = 0;

// The sonar's result goes to the core one step after it asked for the ping.
bool sonar_pending = false;
uint16_t sonar_range_mm = 0;

core::Inputs in;
core::Outputs out;
uint8_t rx[kRxChunk];

}  // namespace

void setup() {
  hal::HwWatchdog::enable();
  hal::StatusLed::begin(true);
  motors.begin();
  servo.begin(0);
  sonar.begin();
  serial_link.begin(board::kSerialBaud);
  const uint16_t boot_id = hal::BootCounter::increment();

  // A gyro that does not answer is not waited for: the core sees no samples and reports
  // a gyro fault within gyro_timeout_ms, and the rover stays still and talks.
  hal::HwWatchdog::kick();
  gyro_state = gyro.begin();
  hal::HwWatchdog::kick();
  if (hal::mpu_usable(gyro_state)) {
    gyro.calibrate(board::kGyroCalSamples, board::kGyroCalMaxMs, hal::HwWatchdog::kick);
  }
  hal::StatusLed::set(!hal::mpu_usable(gyro_state));
  rover.begin(boot_id, hal::HwWatchdog::reset_flags());
  last_step_ms = millis();
}

void loop() {
  hal::HwWatchdog::kick();
  const uint32_t now_ms = millis();
  if (now_ms - last_step_ms < kStepMs) return;
  last_step_ms = now_ms;

  in.now_ms = now_ms;
  int32_t rate_mdps = 0;
  in.gyro_valid = hal::mpu_usable(gyro_state) && gyro.read_rate_mdps(rate_mdps) == hal::MpuResult::Ok;
  in.gyro_rate_mdps = rate_mdps;
  in.sonar_valid = sonar_pending;
  in.sonar_range_mm = sonar_range_mm;
  sonar_pending = false;
  in.wheels_valid = false;  // the seed's rover has no encoders
  in.rx_len = serial_link.read_some(rx, sizeof rx);
  in.rx = rx;
  in.tx_room = serial_link.tx_free();

  rover.step(in, out);

  motors.set(out.left_pwm, out.right_pwm);
  servo.write_cdeg(out.servo_cdeg);
  serial_link.write_some(out.tx, out.tx_len);
  if (out.fire_sonar) {
    uint16_t range_mm = 0;
    const hal::SonarResult r = sonar.ping(now_ms, range_mm);
    sonar_pending = true;
    sonar_range_mm = r == hal::SonarResult::Ok ? range_mm : 0;
  }
  hal::StatusLed::set(rover.fault() != FaultCode::None);
}
