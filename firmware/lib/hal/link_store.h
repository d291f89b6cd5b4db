// The link's key and signing counters in the ATmega328P's EEPROM (board.h: kEepromLinkAddr).
//
//   offset  bytes  what
//   0       1      key record: 0xA5 when a key is stored (anything else: none)
//   1       16     the key
//   17      2      CRC-16/CCITT-FALSE of the 17 bytes before it, xor the fleet id ([fleet]: 0 a lone
//                  rover, 1..kMaxRovers rover k of a fleet): the CRC covers it and the record keeps
//                  its size, so that a record written before fleets is a lone rover's, byte for
//                  byte (its key kept, the counter slots where they were); a record whose CRC is off
//                  by more than kMaxRovers is broken (no key, a lone rover)
//   19      2x15   counter slots A and B: tx counter (6), rx counter (6), age (1, +1 a write,
//                  wrapping), CRC-16 of the 13 (2)
//
// Counters go to the slot not holding the newest record, so a write cut short by a reset
// leaves the other slot whole; load() takes the valid slot with the newer age. Written when a
// counter passes a multiple of kSignPersistStep (Rover::persist_due): while the host talks, once
// every 65.5 s of its clock; 100,000 writes a cell, two slots in turn: 150 days of continuous use.
//
// Writes never wait: an EEPROM byte takes 3.4 ms, so poll() starts one byte a step when the
// last has finished (EEPE clear), 15-19 steps for a record. Reads are immediate.
#pragma once

#include <stdint.h>

#include "rover.h"

namespace rovernav {
namespace hal {

class LinkStore {
 public:
  /// The stored key, fleet id and counters (no key: has_key false; no valid key record: fleet 0;
  /// counters 0 if no slot is valid).
  void load(core::LinkSecrets& out);
  /// Queue a record: the key (nullptr erases it) and the fleet id (0..kMaxRovers), or the counters.
  /// False while one is still being written (call again next step).
  bool store_key(const uint8_t* key, uint8_t fleet_id);
  bool store_counters(const Counter48& tx, const Counter48& rx);
  /// One byte a call, when the EEPROM is free; call every step.
  void poll();
  bool busy() const { return left_ > 0; }

 private:
  void start(uint16_t addr, uint8_t n);

  uint8_t buf_[19] = {};
  uint16_t addr_ = 0;   // the next byte's address
  uint8_t left_ = 0;
  uint8_t done_ = 0;
  uint8_t next_slot_ = 0;   // the slot load() did not take
  uint8_t age_ = 0;         // the age the next counter record gets
};

}  // namespace hal
}  // namespace rovernav
