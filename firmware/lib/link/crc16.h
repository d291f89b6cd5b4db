// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, not reflected, xorout 0.
// Catalogue check value: crc16_ccitt_false("123456789", 9) == 0x29B1.
#pragma once
#include <stdint.h>

namespace rovernav {

/// Continues a CRC over one more byte (start from kCrc16Init).
uint16_t crc16_update(uint16_t crc, uint8_t byte);

enum : uint16_t { kCrc16Init = 0xFFFF };

/// CRC of len bytes at data.
uint16_t crc16_ccitt_false(const uint8_t* data, uint16_t len);

}  // namespace rovernav
