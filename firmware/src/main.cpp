// The Arduino shell of the rover: owns the drivers, moves bytes between the serial port and
// the link codec, and kicks the watchdog. Everything that touches a pin is here or in lib/hal;
// the autonomy core (lib/core) will be called from loop() once it exists.
#include <Arduino.h>

#include "board.h"
#include "boot_counter.h"
#include "frame.h"
#include "hw_watchdog.h"
#include "link_serial.h"
#include "messages_gen.h"
#include "motors.h"
#include "mpu6050.h"
#include "servo_timer1.h"
#include "sonar_hcsr04.h"

namespace {

using namespace rovernav;

// Start-up problems, one bit each; the LED stays lit while any is set.
enum StartFault : uint8_t {
  kStartFaultGyro = 1,      // gyro did not answer or is not an MPU-6050
  kStartFaultGyroCal = 2,   // gyro bias not calibrated (rover moved or bus failed)
};

constexpr uint8_t kRxChunk = 32;

hal::Motors motors;
hal::ServoTimer1 servo;
hal::SonarHcsr04 sonar;
hal::Mpu6050 gyro;
hal::LinkSerial serial_link;
FrameDecoder decoder;

uint8_t start_faults = 0;
uint32_t boot_id = 0;
uint8_t tx_seq = 0;
bool host_schema_ok = false;

hal::MpuResult gyro_result = hal::MpuResult::NotStarted;
uint32_t last_gyro_ms = 0;
int32_t yaw_rate_mdps = 0;

// One encoded frame at a time leaves through the serial TX buffer, in pieces if need be.
uint8_t tx_frame[kMaxEncodedFrame];
uint8_t tx_len = 0;
uint8_t tx_sent = 0;
uint16_t tx_dropped = 0;

void drain_tx() {
  if (tx_len == 0) return;
  const uint8_t left = static_cast<uint8_t>(tx_len - tx_sent);
  tx_sent = static_cast<uint8_t>(tx_sent + serial_link.write_some(tx_frame + tx_sent, left));
  if (tx_sent == tx_len) tx_len = tx_sent = 0;
}

// Drops (and counts) the message when the previous frame has not left yet.
template <typename Msg>
void send(const Msg& message) {
  drain_tx();
  if (tx_len != 0) {
    ++tx_dropped;
    return;
  }
  tx_len = encode_message(message, tx_seq++, tx_frame);
  tx_sent = 0;
  drain_tx();
}

void send_hello() {
  msg::Hello hello;
  hello.schema_hash = kSchemaHash;
  hello.boot_id = boot_id;
  hello.firmware_version = board::kFirmwareVersion;
  hello.role = static_cast<uint8_t>(Role::Rover);
  hello.max_waypoints = kMaxWaypoints;
  send(hello);
}

void on_frame(const Frame& frame) {
  msg::Hello hello;
  if (decode_message(frame, hello)) {
    host_schema_ok = hello.schema_hash == kSchemaHash;
    send_hello();
  }
}

void receive() {
  uint8_t rx[kRxChunk];
  const uint8_t n = serial_link.read_some(rx, sizeof rx);
  for (uint8_t i = 0; i < n; ++i) {
    if (decoder.push(rx[i])) on_frame(decoder.frame());
  }
}

void read_gyro(uint32_t now_ms) {
  if (!hal::mpu_usable(gyro_result)) return;
  if (now_ms - last_gyro_ms < hal::Mpu6050::kSamplePeriodMs) return;
  last_gyro_ms = now_ms;
  int32_t rate_mdps = 0;
  if (gyro.read_rate_mdps(rate_mdps) == hal::MpuResult::Ok) yaw_rate_mdps = rate_mdps;
}

}  // namespace

void setup() {
  hal::HwWatchdog::enable();
  pinMode(board::kPinLed, OUTPUT);
  digitalWrite(board::kPinLed, HIGH);

  motors.begin();
  servo.begin(0);
  sonar.begin();
  serial_link.begin(board::kSerialBaud);
  boot_id = hal::BootCounter::increment();

  hal::HwWatchdog::kick();
  gyro_result = gyro.begin();
  hal::HwWatchdog::kick();
  if (!hal::mpu_usable(gyro_result)) {
    start_faults |= kStartFaultGyro | kStartFaultGyroCal;
  } else if (gyro.calibrate(board::kGyroCalSamples, board::kGyroCalMaxMs,
                            hal::HwWatchdog::kick) != hal::MpuResult::Ok) {
    start_faults |= kStartFaultGyroCal;
  }

  digitalWrite(board::kPinLed, start_faults != 0 ? HIGH : LOW);
  send_hello();
}

void loop() {
  hal::HwWatchdog::kick();
  const uint32_t now_ms = millis();
  receive();
  read_gyro(now_ms);
  drain_tx();
}
