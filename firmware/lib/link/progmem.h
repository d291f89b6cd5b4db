// Constant tables in flash. On the AVR, data is copied to SRAM at start-up unless it is marked
// PROGMEM and read with pgm_read_*; elsewhere these are plain const reads.
#pragma once
#include <stdint.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define ROVERNAV_PROGMEM PROGMEM
namespace rovernav {
inline int32_t flash_read_i32(const int32_t* p) { return static_cast<int32_t>(pgm_read_dword(p)); }
inline int16_t flash_read_i16(const int16_t* p) { return static_cast<int16_t>(pgm_read_word(p)); }
inline int8_t flash_read_i8(const int8_t* p) { return static_cast<int8_t>(pgm_read_byte(p)); }
inline uint8_t flash_read_u8(const uint8_t* p) { return pgm_read_byte(p); }
inline float flash_read_float(const float* p) { return pgm_read_float(p); }
}  // namespace rovernav
#else
#define ROVERNAV_PROGMEM
namespace rovernav {
inline int32_t flash_read_i32(const int32_t* p) { return *p; }
inline int16_t flash_read_i16(const int16_t* p) { return *p; }
inline int8_t flash_read_i8(const int8_t* p) { return *p; }
inline uint8_t flash_read_u8(const uint8_t* p) { return *p; }
inline float flash_read_float(const float* p) { return *p; }
}  // namespace rovernav
#endif
