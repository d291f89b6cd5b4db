#include "twi_master.h"

#include <Arduino.h>
#include <avr/io.h>
#include <util/twi.h>

namespace rovernav {
namespace hal {

namespace {

// TW_STATUS values are multiples of 8, so this cannot be mistaken for one.
constexpr uint8_t kStatusTimedOut = 0xFF;

// Hands the bus to the TWI for one step (a START, a byte, a STOP) by clearing TWINT, with
// `flags` (TWSTA, TWSTO, TWEA) saying which step.
__attribute__((noinline)) void clear_twint(uint8_t flags) {
  TWCR = static_cast<uint8_t>(_BV(TWINT) | _BV(TWEN) | flags);
}

// Polls TWCR until (TWCR & mask) == wanted; false when kStepTimeoutUs passes first.
bool wait_for_twcr(uint8_t mask, uint8_t wanted) {
  // 16 bits of micros() span 65 ms, far more than one step; the subtraction wraps correctly.
  const uint16_t start_us = static_cast<uint16_t>(micros());
  while ((TWCR & mask) != wanted) {
    const uint16_t waited_us = static_cast<uint16_t>(static_cast<uint16_t>(micros()) - start_us);
    if (waited_us > TwiMaster::kStepTimeoutUs) return false;
  }
  return true;
}

// Runs one step that ends with TWINT set and returns TWSR's status, or kStatusTimedOut.
uint8_t run_step(uint8_t flags) {
  clear_twint(flags);
  if (!wait_for_twcr(_BV(TWINT), _BV(TWINT))) return kStatusTimedOut;
  return static_cast<uint8_t>(TW_STATUS);
}

TwiResult result_of(uint8_t status, uint8_t expected) {
  if (status == expected) return TwiResult::Ok;
  if (status == kStatusTimedOut) return TwiResult::Timeout;
  if (status == TW_MT_SLA_NACK || status == TW_MR_SLA_NACK) return TwiResult::NoAck;
  return TwiResult::BusError;
}

TwiResult step(uint8_t flags, uint8_t expected) { return result_of(run_step(flags), expected); }

__attribute__((noinline)) TwiResult send_byte(uint8_t byte, uint8_t expected) {
  TWDR = byte;
  return step(0, expected);
}

// START and SLA+W: the master transmitter owns the bus.
TwiResult start_write(uint8_t address) {
  const TwiResult r = step(_BV(TWSTA), TW_START);
  if (r != TwiResult::Ok) return r;
  return send_byte(static_cast<uint8_t>(address << 1 | TW_WRITE), TW_MT_SLA_ACK);
}

// Repeated START and SLA+R: the bus is kept and turned round for reading.
TwiResult restart_read(uint8_t address) {
  const TwiResult r = step(_BV(TWSTA), TW_REP_START);
  if (r != TwiResult::Ok) return r;
  return send_byte(static_cast<uint8_t>(address << 1 | TW_READ), TW_MR_SLA_ACK);
}

// Ends every transaction. After a timeout the TWI is reset; otherwise a STOP is sent, which
// also releases the bus after lost arbitration or a bus error. TWSTO clears once the STOP has
// gone out: the next START must not be queued behind it.
TwiResult finish(TwiResult r) {
  if (r == TwiResult::Timeout) {
    TwiMaster::reset();
    return r;
  }
  clear_twint(_BV(TWSTO));
  if (!wait_for_twcr(_BV(TWSTO), 0)) {
    TwiMaster::reset();
    return TwiResult::Timeout;
  }
  return r;
}

}  // namespace

void TwiMaster::begin(uint32_t clock_hz) {
  PORTC = static_cast<uint8_t>(PORTC | _BV(PORTC4) | _BV(PORTC5));  // SDA, SCL pull-ups
  TWSR = 0;                                                          // prescaler 1
  // SCL = F_CPU / (16 + 2 * TWBR): 12 for 400 kHz.
  TWBR = static_cast<uint8_t>((F_CPU / clock_hz - 16) / 2);
  TWCR = _BV(TWEN);
}

void TwiMaster::reset() {
  TWCR = 0;
  TWCR = _BV(TWEN);
}

TwiResult TwiMaster::write_reg(uint8_t address, uint8_t reg, uint8_t value) {
  TwiResult r = start_write(address);
  if (r == TwiResult::Ok) r = send_byte(reg, TW_MT_DATA_ACK);
  if (r == TwiResult::Ok) r = send_byte(value, TW_MT_DATA_ACK);
  return finish(r);
}

TwiResult TwiMaster::read_regs(uint8_t address, uint8_t reg, uint8_t* out, uint8_t count) {
  if (count == 0) return TwiResult::Ok;
  TwiResult r = start_write(address);
  if (r == TwiResult::Ok) r = send_byte(reg, TW_MT_DATA_ACK);
  if (r == TwiResult::Ok) r = restart_read(address);
  for (uint8_t i = 0; r == TwiResult::Ok && i < count; ++i) {
    // ACK asks the slave for another byte; the last one is NACKed so it lets go of SDA.
    const bool last = i + 1 == count;
    r = step(last ? 0 : _BV(TWEA), last ? TW_MR_DATA_NACK : TW_MR_DATA_ACK);
    if (r == TwiResult::Ok) out[i] = TWDR;
  }
  return finish(r);
}

}  // namespace hal
}  // namespace rovernav
