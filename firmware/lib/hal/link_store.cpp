#include "link_store.h"

#include <avr/eeprom.h>
#include <avr/io.h>
#include <stddef.h>
#include <string.h>

#include "board.h"
#include "crc16.h"

namespace rovernav {
namespace hal {

namespace {
enum : uint8_t { kKeyMagic = 0xA5, kKeyRecord = 19, kSlotBytes = 15, kSlotData = 13 };
const uint16_t kKeyAddr = board::kEepromLinkAddr;
const uint16_t kSlotAddr = board::kEepromLinkAddr + kKeyRecord;

void read(uint16_t addr, uint8_t* out, uint8_t n) {
  eeprom_read_block(out, reinterpret_cast<const void*>(addr), n);
}

/// The record's CRC field xor the CRC of its n bytes: 0 for a whole record (the key record: its fleet id).
uint16_t crc_off(const uint8_t* rec, uint8_t n) {
  return static_cast<uint16_t>(crc16_ccitt_false(rec, n) ^ static_cast<uint16_t>(rec[n] | (rec[n + 1] << 8)));
}

void put_crc(uint8_t* rec, uint8_t n, uint8_t xor_low = 0) {
  const uint16_t crc = crc16_ccitt_false(rec, n);
  rec[n] = static_cast<uint8_t>(crc ^ xor_low);
  rec[n + 1] = static_cast<uint8_t>(crc >> 8);
}
}  // namespace

static_assert(offsetof(core::LinkSecrets, rx_counter) == offsetof(core::LinkSecrets, tx_counter) + sizeof(Counter48),
              "the counters lie as in a slot: tx then rx");

void LinkStore::load(core::LinkSecrets& out) {
  uint8_t* rec = buf_;   // nothing is being written yet: the write buffer holds what is read
  read(kKeyAddr, rec, kKeyRecord);
  const uint16_t fleet = crc_off(rec, 17);
  const bool whole = fleet <= kMaxRovers;
  out.has_key = rec[0] == kKeyMagic && whole;
  out.fleet_id = whole ? static_cast<uint8_t>(fleet) : 0;
  memcpy(out.key, rec + 1, kSipKeyBytes);
  memset(&out.tx_counter, 0, 2 * sizeof(Counter48));
  bool found = false;
  for (uint8_t s = 0; s < 2; ++s) {
    read(static_cast<uint16_t>(kSlotAddr + s * kSlotBytes), rec, kSlotBytes);
    // ages are 8-bit and each write adds one: the newer slot is a small step ahead
    if (crc_off(rec, kSlotData) != 0 || (found && static_cast<uint8_t>(rec[12] - age_) >= 128)) continue;
    found = true;
    age_ = rec[12];
    next_slot_ = static_cast<uint8_t>(s ^ 1);
    memcpy(&out.tx_counter, rec, 2 * sizeof(Counter48));   // tx then rx, as in the slot
  }
}

// Left to LTO (it pastes it into its two callers): kept out of line it cost 10 bytes of flash
// with avr-gcc 7.3 and 4 with 5.4.
void LinkStore::start(uint16_t addr, uint8_t n) {
  addr_ = addr;
  left_ = n;
  done_ = 0;
}

bool LinkStore::store_key(const uint8_t* key, uint8_t fleet_id) {
  if (busy()) return false;
  buf_[0] = key != nullptr ? kKeyMagic : 0xFF;
  for (uint8_t i = 0; i < kSipKeyBytes; ++i) buf_[1 + i] = key != nullptr ? key[i] : 0xFF;
  put_crc(buf_, 17, fleet_id);
  start(kKeyAddr, kKeyRecord);
  return true;
}

bool LinkStore::store_counters(const Counter48& tx, const Counter48& rx) {
  if (busy()) return false;
  for (uint8_t i = 0; i < kSignCounterBytes; ++i) {
    buf_[i] = tx.b[i];
    buf_[6 + i] = rx.b[i];
  }
  ++age_;
  buf_[12] = age_;
  put_crc(buf_, kSlotData);
  start(static_cast<uint16_t>(kSlotAddr + next_slot_ * kSlotBytes), kSlotBytes);
  next_slot_ ^= 1;
  return true;
}

void LinkStore::poll() {
  if (left_ == 0 || (EECR & _BV(EEPE))) return;
  // One byte, started and left to finish (3.4 ms) on its own: avr-libc's eeprom_write_byte
  // waits only for the previous write, which EEPE shows has ended.
  eeprom_write_byte(reinterpret_cast<uint8_t*>(addr_ + done_), buf_[done_]);
  ++done_;
  --left_;
}

}  // namespace hal
}  // namespace rovernav
