// The Arduino shell of the rover: reads the sensors, steps the autonomy core every 10 ms, and
// applies what it asks for to the pins. Everything that touches hardware is here or in lib/hal;
// every decision is in lib/core, which the native tests and the simulator run unchanged.
//
// Nothing here waits on a sensor: the gyro read has a time limit in its driver, the sonar's
// echo is timed by an interrupt and collected by a later step, serial writes never exceed the
// room in the TX buffer, and the watchdog resets the board if a loop ever takes longer than
// 250 ms.
//
// Measurement hooks (for a scope, and for the AVR simulator that times the image): D8 (PB0) is
// high while a step works; at the end of each step GPIOR0 holds what the step did: bits 0-3 the
// rover's state, bit 4 a FIX was taken in, bit 5 the sonar was triggered or its result
// collected, bit 6 the detour planner ran, bit 7 radio bytes came in.
#include <Arduino.h>

#include "board.h"
#include "boot_counter.h"
#include "clock.h"
#include "hw_watchdog.h"
#include "link_serial.h"
#include "link_store.h"
#include "motors.h"
#include "mpu6050.h"
#include "rover.h"
#include "servo_timer1.h"
#include "sonar_hcsr04.h"
#include "status_led.h"

namespace {

using namespace rovernav;

constexpr uint8_t kStepMs = kStepPeriodMs;       // protocol/vehicle.toml: the core runs at 100 Hz
constexpr uint8_t kRxChunk = kUartBufferBytes;   // a read takes at most what the RX buffer holds

core::Rover rover;
core::Outputs out;
hal::Motors motors;
hal::ServoTimer1 servo;
hal::SonarHcsr04 sonar;
hal::Mpu6050 gyro;
hal::LinkSerial serial_link;
hal::LinkStore link_store;

// What the gyro's begin() said. setup() sets it before loop() first reads it, so its start value
// is never seen: zero, in .bss (an initialised global would bring the start-up copy loop back).
hal::MpuResult gyro_state;
uint16_t last_step_ms = 0;   // modulo 65,536: loop() looks at it every few microseconds

// A ping the core asked for is triggered after its step; the result, collected by the poll at
// the start of a later step (the next one, for echoes within 1 m), goes to the core in that step.
bool sonar_pending = false;
uint16_t sonar_range_mm = 0;

enum : uint8_t {
  kDidFix = 1u << 4,
  kDidSonar = 1u << 5,
  kDidPlan = 1u << 6,
  kDidRx = 1u << 7,
};

uint8_t rx[kRxChunk];
uint8_t rx_len = 0;   // bytes in rx the core has not taken yet (it takes one signed frame a step)

}  // namespace

void setup() {
  hal::HwWatchdog::enable();
  hal::StatusLed::begin(true);
  DDRB = static_cast<uint8_t>(DDRB | _BV(DDB0));   // the step probe (board::kPinStepProbe)
  PORTD = static_cast<uint8_t>(PORTD | _BV(PORTD7));   // the consent pin's pull-up (board::kPinConsent), read below
  motors.begin();
  servo.begin(0);
  sonar.begin();
  serial_link.begin(board::kSerialBaud);
  // A frame delimiter first: a reset may have cut a frame short, and the host must not take
  // that half frame and our HELLO for one (bad CRC: the new boot id would go unheard).
  const uint8_t delimiter = 0x00;
  serial_link.write_some(&delimiter, 1);
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
  {
    core::LinkSecrets secrets;   // on the stack for setup() only: the core keeps its own copy
    link_store.load(secrets);
    // The consent pin held to GND (its pull-up has had the gyro's calibration to settle): the
    // owner's consent to an unsigned PROVISION, for the core (a bit of the reset cause: PD7 low
    // is that bit set, as it is the same bit).
    static_assert(kSignConsentResetBit == _BV(PIND7), "the consent pin's bit in PIND is its reset cause bit");
    const uint8_t consent = static_cast<uint8_t>(~PIND & _BV(PIND7));
    rover.begin(boot_id, static_cast<uint8_t>(hal::HwWatchdog::reset_flags() | consent), &secrets);
  }
  last_step_ms = static_cast<uint16_t>(hal::clock_ms());
}

void loop() {
  hal::HwWatchdog::kick();
  const uint32_t now_ms = hal::clock_ms();
  const uint16_t since_ms = static_cast<uint16_t>(static_cast<uint16_t>(now_ms) - last_step_ms);
  if (since_ms < kStepMs) return;
  // On the 10 ms grid, not 10 ms after whenever this step began: millis() moves in 1.024 ms
  // ticks, and `last = now` let the period drift to 10.04 ms. Far behind (a stall), resync.
  last_step_ms = since_ms < 2 * kStepMs ? static_cast<uint16_t>(last_step_ms + kStepMs) : static_cast<uint16_t>(now_ms);
  PORTB = static_cast<uint8_t>(PORTB | _BV(PORTB0));
  uint8_t did = 0;

  uint16_t echo_mm = 0;
  const hal::SonarResult polled = sonar.poll(micros(), echo_mm);
  if (polled != hal::SonarResult::Pending && polled != hal::SonarResult::Idle) {
    sonar_pending = true;
    sonar_range_mm = polled == hal::SonarResult::Ok ? echo_mm : 0;
    did |= kDidSonar;
  }

  core::Inputs in;   // what this step reads, on the stack for the step only
  in.now_ms = now_ms;
  int32_t rate_mdps = 0;
  in.gyro_valid = hal::mpu_usable(gyro_state) && gyro.read_rate_mdps(rate_mdps) == hal::MpuResult::Ok;
  in.gyro_rate_mdps = rate_mdps;
  in.sonar_valid = sonar_pending;
  in.sonar_range_mm = sonar_range_mm;
  sonar_pending = false;
  in.wheels_valid = false;  // the seed's rover has no encoders (nor does the core read them: io.h)
  rx_len = static_cast<uint8_t>(rx_len + serial_link.read_some(rx + rx_len, static_cast<uint8_t>(sizeof rx - rx_len)));
  in.rx_len = rx_len;
  in.rx = rx;
  in.tx_room = serial_link.tx_free();

  rover.step(in, out);

  // What the core did not take comes first next step.
  rx_len = static_cast<uint8_t>(rx_len - out.rx_used);
  for (uint8_t i = 0; i < rx_len; ++i) rx[i] = rx[out.rx_used + i];
  // The link key and counters to EEPROM, a byte a step (link_store.h).
  if (!link_store.busy()) {
    const uint8_t change = rover.take_key_change();
    Counter48 tx_counter, rx_counter;
    if (change != 0) {
      link_store.store_key(change == core::Rover::kKeyStore ? rover.link_key() : nullptr, rover.fleet_id());
    } else if (rover.persist_due(tx_counter, rx_counter)) {
      link_store.store_counters(tx_counter, rx_counter);
    }
  }
  link_store.poll();

  motors.set(out.left_pwm, out.right_pwm);
  servo.write_cdeg(out.servo_cdeg);
  serial_link.write_some(out.tx, out.tx_len);
  if (out.fire_sonar) {
    did |= kDidSonar;
    if (sonar.trigger(now_ms) != hal::SonarResult::Pending) {
      sonar_pending = true;   // not sent (too soon, echo still high, no sensor): "nothing" next step
      sonar_range_mm = 0;
    }
  }
  hal::StatusLed::set(rover.fault() != FaultCode::None);
  const uint8_t work = rover.step_work();
  if (work & core::Rover::kWorkFix) did |= kDidFix;
  if (work & core::Rover::kWorkPlanned) did |= kDidPlan;
  if (out.rx_used > 0) did |= kDidRx;
  GPIOR0 = static_cast<uint8_t>(did | (static_cast<uint8_t>(rover.state()) & 0x0Fu));
  PORTB = static_cast<uint8_t>(PORTB & ~_BV(PORTB0));
}
