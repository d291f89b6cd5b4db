#include "crc16.h"

namespace rovernav {

// Bitwise, no table: 512 bytes of table would be a quarter of the Uno's SRAM, and at
// 57,600 baud the rover handles at most ~5,800 bytes a second.
uint16_t crc16_update(uint16_t crc, uint8_t byte) {
  crc = static_cast<uint16_t>(crc ^ (static_cast<uint16_t>(byte) << 8));
  for (uint8_t bit = 0; bit < 8; ++bit) {
    const unsigned shifted = static_cast<unsigned>(crc) << 1;
    crc = static_cast<uint16_t>((crc & 0x8000u) ? (shifted ^ 0x1021u) : shifted);
  }
  return crc;
}

uint16_t crc16_ccitt_false(const uint8_t* data, uint16_t len) {
  uint16_t crc = kCrc16Init;
  for (uint16_t i = 0; i < len; ++i) crc = crc16_update(crc, data[i]);
  return crc;
}

}  // namespace rovernav
