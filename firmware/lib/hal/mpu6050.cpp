#include "mpu6050.h"

#include <Arduino.h>

#include "clock.h"
#include "twi_master.h"

namespace rovernav {
namespace hal {

namespace {

constexpr uint8_t kRegSmplrtDiv = 0x19;
constexpr uint8_t kRegConfig = 0x1A;
constexpr uint8_t kRegGyroConfig = 0x1B;
constexpr uint8_t kRegGyroZoutH = 0x47;
constexpr uint8_t kRegPwrMgmt1 = 0x6B;
constexpr uint8_t kRegWhoAmI = 0x75;

constexpr uint8_t kPwrReset = 0x80;
constexpr uint8_t kPwrClockPllGyroX = 0x01;
constexpr uint8_t kDlpf42Hz = 0x03;
constexpr uint8_t kSmplrtDiv100Hz = 9;
constexpr uint8_t kGyroFs500Dps = 0x08;
constexpr uint8_t kWhoAmIMpu6050 = 0x68;
constexpr uint16_t kResetSettleMs = 100;

// The configuration written after the reset, register and value, in order. In flash: a table in
// RAM is initialised data, which costs the image the start-up copy loop as well as the copy.
const uint8_t kConfig[][2] PROGMEM = {
    {kRegPwrMgmt1, kPwrClockPllGyroX},
    {kRegConfig, kDlpf42Hz},
    {kRegSmplrtDiv, kSmplrtDiv100Hz},
    {kRegGyroConfig, kGyroFs500Dps},
};

bool is_clone_id(uint8_t id) { return id == 0x70 || id == 0x72 || id == 0x98; }

// An if-chain, not a switch: GCC turns that switch into a lookup table in RAM.
__attribute__((noinline)) MpuResult from_twi(TwiResult r) {
  if (r == TwiResult::Ok) return MpuResult::Ok;
  if (r == TwiResult::NoAck) return MpuResult::NotFound;
  if (r == TwiResult::Timeout) return MpuResult::Timeout;
  return MpuResult::BusError;
}

}  // namespace

// Out of line: pasted at begin()'s two writes it cost 6 bytes of flash with avr-gcc 7.3 and 4 with
// 5.4 (read_regs is better pasted: out of line, 5.4's image grew by 88).
__attribute__((noinline)) MpuResult Mpu6050::write_reg(uint8_t reg, uint8_t value) {
  return from_twi(TwiMaster::write_reg(board::kMpuAddress, reg, value));
}

MpuResult Mpu6050::read_regs(uint8_t reg, uint8_t* out, uint8_t count) {
  return from_twi(TwiMaster::read_regs(board::kMpuAddress, reg, out, count));
}

MpuResult Mpu6050::begin() {
  started_ = false;
  TwiMaster::begin(board::kI2cClockHz);

  MpuResult r = read_regs(kRegWhoAmI, &who_am_i_, 1);
  if (r != MpuResult::Ok) return r;
  MpuResult identity = MpuResult::Ok;
  if (who_am_i_ != kWhoAmIMpu6050) {
    if (!is_clone_id(who_am_i_)) return MpuResult::WrongId;
    identity = MpuResult::CloneId;
  }

  r = write_reg(kRegPwrMgmt1, kPwrReset);
  if (r != MpuResult::Ok) return r;
  delay(kResetSettleMs);

  for (const auto& reg_value : kConfig) {
    r = write_reg(pgm_read_byte(&reg_value[0]), pgm_read_byte(&reg_value[1]));
    if (r != MpuResult::Ok) return r;
  }
  started_ = true;
  return identity;
}

__attribute__((noinline)) MpuResult Mpu6050::read_chip_rate_mdps(int32_t& rate_mdps) {
  if (!started_) return MpuResult::NotStarted;
  uint8_t bytes[2];
  const MpuResult r = read_regs(kRegGyroZoutH, bytes, 2);
  if (r != MpuResult::Ok) return r;
  const int16_t counts = static_cast<int16_t>(static_cast<uint16_t>(bytes[0]) << 8 | bytes[1]);
  // mdps = counts * 1000 / 65.5 = counts * 2000 / 131, rounded half away from zero.
  const int32_t scaled = static_cast<int32_t>(counts) * 2000;
  rate_mdps = (scaled >= 0 ? scaled + kCountsPer2Dps / 2 : scaled - kCountsPer2Dps / 2) /
              kCountsPer2Dps;
  return MpuResult::Ok;
}

MpuResult Mpu6050::read_rate_mdps(int32_t& rate_mdps) {
  int32_t chip_mdps = 0;
  const MpuResult r = read_chip_rate_mdps(chip_mdps);
  if (r != MpuResult::Ok) return r;
  rate_mdps = board::kGyroZToClockwiseSign * (chip_mdps - bias_mdps_);
  return MpuResult::Ok;
}

MpuResult Mpu6050::calibrate(uint16_t samples, uint16_t max_ms, void (*idle)()) {
  if (!started_) return MpuResult::NotStarted;
  if (samples == 0) return MpuResult::Ok;
  // Times modulo 65,536, as max_ms is: the loop looks at the clock every few milliseconds and
  // ends once max_ms have passed, so no difference it takes reaches 65,536. Two bytes a time,
  // not four, leave registers for the sums below (it took 62 bytes less flash).
  const uint16_t start_ms = static_cast<uint16_t>(clock_ms());
  uint16_t last_sample_ms = static_cast<uint16_t>(start_ms - kSamplePeriodMs);
  // Sums offsets from the first sample: each is within kGyroCalMaxSpreadMdps, so 65,535 of
  // them fit an int32_t.
  int32_t first_mdps = 0;
  int32_t min_mdps = 0;
  int32_t max_mdps = 0;
  int32_t sum_offset_mdps = 0;
  uint16_t taken = 0;
  while (taken < samples) {
    const uint16_t now_ms = static_cast<uint16_t>(clock_ms());
    if (static_cast<uint16_t>(now_ms - start_ms) > max_ms) return MpuResult::CalTimeout;
    if (static_cast<uint16_t>(now_ms - last_sample_ms) < kSamplePeriodMs) {
      if (idle != nullptr) idle();
      continue;
    }
    last_sample_ms = now_ms;
    int32_t mdps = 0;
    const MpuResult r = read_chip_rate_mdps(mdps);
    if (r != MpuResult::Ok) return r;
    if (taken == 0) first_mdps = mdps;
    const int32_t offset_mdps = mdps - first_mdps;
    if (offset_mdps < min_mdps) min_mdps = offset_mdps;
    if (offset_mdps > max_mdps) max_mdps = offset_mdps;
    if (max_mdps - min_mdps > board::kGyroCalMaxSpreadMdps) return MpuResult::Moving;
    sum_offset_mdps += offset_mdps;
    ++taken;
  }
  bias_mdps_ = first_mdps + sum_offset_mdps / static_cast<int32_t>(samples);
  return MpuResult::Ok;
}

}  // namespace hal
}  // namespace rovernav
