// The ATmega328P's TWI (I2C) as a polled bus master for register reads and writes, every
// wait bounded. No buffers and no interrupt: it costs no RAM.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// TWSR status codes this driver handles (ATmega328P datasheet, 2-wire Serial Interface,
// master transmitter and master receiver modes; avr-libc's <util/twi.h> names):
//
//   TWSR  name             after                          here
//   0x08  TW_START         START sent                     send SLA+W
//   0x10  TW_REP_START     repeated START sent            send SLA+R
//   0x18  TW_MT_SLA_ACK    SLA+W sent, ACK                send the register
//   0x20  TW_MT_SLA_NACK   SLA+W sent, NACK               NoAck, STOP
//   0x28  TW_MT_DATA_ACK   data byte sent, ACK            next byte or STOP
//   0x30  TW_MT_DATA_NACK  data byte sent, NACK           BusError, STOP
//   0x38  TW_MT_ARB_LOST   arbitration lost               BusError, STOP (releases the bus)
//   0x40  TW_MR_SLA_ACK    SLA+R sent, ACK                read the bytes
//   0x48  TW_MR_SLA_NACK   SLA+R sent, NACK               NoAck, STOP
//   0x50  TW_MR_DATA_ACK   byte received, ACK returned    read the next byte
//   0x58  TW_MR_DATA_NACK  byte received, NACK returned   the last byte: STOP
//   0x00  TW_BUS_ERROR     illegal START or STOP          BusError, STOP (resets the TWI's
//                                                         state, sends nothing)
//   any other                                             BusError, STOP
//
// Every wait for TWINT, and for a STOP to leave, gives up after kStepTimeoutUs: a byte takes
// 23 us at 400 kHz, so only a missing pull-up, a slave holding SCL low or a dead TWI gets
// there. A timeout disables and re-enables the TWI (which drops any half-done transfer) and
// returns Timeout. A transaction is bounded by its steps: a register write has 5 (START,
// SLA+W, register, value, STOP), a read of n bytes n + 6, so 2 bytes take at most 8 ms.
// TWIE stays 0: nothing here runs from an interrupt. The waits count on micros(), so call
// with interrupts enabled (with them off, micros() stops advancing past 1 ms).
enum class TwiResult : uint8_t {
  Ok,
  NoAck,     // nothing acknowledged the address: no device there, or it is not powered
  BusError,  // a data byte was NACKed, arbitration was lost, or the bus saw an illegal state
  Timeout,   // a bus step did not finish within kStepTimeoutUs; the TWI was reset
};

class TwiMaster {
 public:
  static constexpr uint16_t kStepTimeoutUs = 1000;

  // Enables the TWI at clock_hz (prescaler 1, so 31 kHz..400 kHz at 16 MHz) and the internal
  // pull-ups on SDA (A4) and SCL (A5), as the Arduino core does; real boards add 4.7 k.
  static void begin(uint32_t clock_hz);

  // START, SLA+W, reg, value, STOP.
  static TwiResult write_reg(uint8_t address, uint8_t reg, uint8_t value);

  // START, SLA+W, reg, repeated START, SLA+R, count bytes (ACK on all but the last, NACK on
  // the last), STOP. out is written only as far as bytes arrived. count 0 reads nothing.
  static TwiResult read_regs(uint8_t address, uint8_t reg, uint8_t* out, uint8_t count);

  // Disables and re-enables the TWI: the bus lines are released and a transfer in flight is
  // dropped. The clock setting stays.
  static void reset();
};

}  // namespace hal
}  // namespace rovernav
