// Constant tables in flash. On the AVR, data is copied to SRAM at start-up unless it is marked
// PROGMEM and read with pgm_read_*; elsewhere these are plain const reads.
#pragma once
#include <stdint.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define ROVERNAV_PROGMEM PROGMEM
namespace rovernav {
inline int32_t flash_read_i32(const int32_t* p) { return static_cast<int32_t>(pgm_read_dword(p)); }
}  // namespace rovernav
#else
#define ROVERNAV_PROGMEM
namespace rovernav {
inline int32_t flash_read_i32(const int32_t* p) { return *p; }
}  // namespace rovernav
#endif
