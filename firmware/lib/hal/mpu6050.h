// MPU-6050 gyro Z rate over I2C (TwiMaster), polled, every bus wait bounded.
#pragma once

#include <stdint.h>

#include "board.h"

namespace rovernav {
namespace hal {

// Registers used (MPU-6000/6050 register map rev 4.2), device address 0x68 (AD0 low):
//
//   reg   name          written   meaning
//   0x6B  PWR_MGMT_1    0x80      DEVICE_RESET; the chip needs 100 ms afterwards
//   0x6B  PWR_MGMT_1    0x01      awake, clock = PLL on gyro X (steadier than the RC oscillator)
//   0x1A  CONFIG        0x03      DLPF_CFG 3: gyro bandwidth 42 Hz, 4.8 ms delay, 1 kHz internal
//   0x19  SMPLRT_DIV    9         output rate 1 kHz / (1 + 9) = 100 Hz
//   0x1B  GYRO_CONFIG   0x08      FS_SEL 1: +-500 deg/s, 65.5 LSB per deg/s
//   0x75  WHO_AM_I      (read)    0x68 on a genuine MPU-6050
//   0x47  GYRO_ZOUT_H   (read)    Z rate, int16 big-endian: 0x47 high byte, 0x48 low byte
//
// Bus: TwiMaster at 400 kHz, every bus step bounded by TwiMaster::kStepTimeoutUs, so a stuck
// bus costs one timeout and a TWI reset, never a hang. Every call returns what happened.
//
// Sign: the chip's Z points up, so its rate is counter-clockwise-positive. read_rate_mdps()
// returns the rover's yaw rate clockwise-positive seen from above, multiplying by
// board::kGyroZToClockwiseSign, the only place that sign is stated.

enum class MpuResult : uint8_t {
  Ok,
  CloneId,    // WHO_AM_I is a known MPU-6500-family clone id (0x70, 0x72, 0x98); configured
  NotFound,   // no ACK at the address: not wired, not powered, or AD0 high
  WrongId,    // something answered with an unknown WHO_AM_I; left alone
  BusError,   // NACK on data, lost arbitration, or an illegal START/STOP on the bus
  Timeout,    // a bus step stalled past TwiMaster::kStepTimeoutUs; the TWI was reset
  NotStarted, // begin() has not succeeded
  Moving,     // calibration saw a spread wider than kGyroCalMaxSpreadMdps; bias unchanged
  CalTimeout, // calibration ran out of time before it had its samples; bias unchanged
};

// True when the gyro can be read (Ok or CloneId).
inline bool mpu_usable(MpuResult r) { return r == MpuResult::Ok || r == MpuResult::CloneId; }

class Mpu6050 {
 public:
  // Raw counts per deg/s at FS_SEL 1 is 65.5, i.e. 131 counts per 2 deg/s.
  static constexpr int32_t kCountsPer2Dps = 131;
  static constexpr uint16_t kSamplePeriodMs = 10;

  // Starts the TWI (400 kHz, bounded), resets and configures the chip. Blocks about 110 ms.
  MpuResult begin();

  // Yaw rate in millidegrees per second, clockwise-positive, bias removed.
  MpuResult read_rate_mdps(int32_t& rate_mdps);

  // Averages `samples` readings at the 100 Hz output rate to find the bias (rover still).
  // Returns within max_ms whatever happens; between samples it calls idle (if not null),
  // which is where the caller kicks its watchdog.
  MpuResult calibrate(uint16_t samples, uint16_t max_ms, void (*idle)());

  int32_t bias_mdps() const { return bias_mdps_; }  // in the chip's frame (CCW positive)
  uint8_t who_am_i() const { return who_am_i_; }
  bool started() const { return started_; }

 private:
  MpuResult write_reg(uint8_t reg, uint8_t value);
  MpuResult read_regs(uint8_t reg, uint8_t* out, uint8_t count);
  MpuResult read_chip_rate_mdps(int32_t& rate_mdps);

  int32_t bias_mdps_ = 0;
  uint8_t who_am_i_ = 0;
  bool started_ = false;
};

}  // namespace hal
}  // namespace rovernav
