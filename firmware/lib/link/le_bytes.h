// Little-endian field access for the link's payloads. No alignment assumptions, no UB:
// every value is assembled byte by byte, so the same code runs on the AVR and on the host.
#pragma once
#include <stdint.h>

namespace rovernav {
namespace le {

inline void put_u8(uint8_t* p, uint8_t v) { p[0] = v; }
inline void put_i8(uint8_t* p, int8_t v) { p[0] = static_cast<uint8_t>(v); }
inline void put_u16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v & 0xFFu);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void put_i16(uint8_t* p, int16_t v) { put_u16(p, static_cast<uint16_t>(v)); }
inline void put_u32(uint8_t* p, uint32_t v) {
  put_u16(p, static_cast<uint16_t>(v & 0xFFFFu));
  put_u16(p + 2, static_cast<uint16_t>(v >> 16));
}
inline void put_i32(uint8_t* p, int32_t v) { put_u32(p, static_cast<uint32_t>(v)); }

inline uint8_t get_u8(const uint8_t* p) { return p[0]; }
inline int8_t get_i8(const uint8_t* p) { return static_cast<int8_t>(p[0]); }
inline uint16_t get_u16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (static_cast<uint16_t>(p[1]) << 8));
}
inline int16_t get_i16(const uint8_t* p) { return static_cast<int16_t>(get_u16(p)); }
inline uint32_t get_u32(const uint8_t* p) {
  return static_cast<uint32_t>(get_u16(p)) | (static_cast<uint32_t>(get_u16(p + 2)) << 16);
}
inline int32_t get_i32(const uint8_t* p) { return static_cast<int32_t>(get_u32(p)); }

}  // namespace le
}  // namespace rovernav
