// The link's messages are laid out in memory as they are on the wire: every field an integer of
// the wire's width held as its little-endian bytes (u16le, i32le, ...: alignment 1, so a message
// struct has no padding on any compiler), in the definition's order. Encoding a message is then
// copying its bytes, decoding it copying them back: no code per field, on the rover or in the
// tests, and no `packed` attribute (whose fields a reference cannot bind to).
//
// A field reads and writes as its integer: `m.x_mm = 300; int16_t x = m.x_mm;`, a plain load or
// store of its bytes on a little-endian target (the AVR, x86, ARM: the only kind this builds for).
#pragma once
#include <stdint.h>
#include <string.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "wire_layout.h: a field's bytes are its integer's only on a little-endian target"
#endif

namespace rovernav {
namespace wire {

/// An integer of type T stored as its sizeof(T) little-endian bytes.
template <typename T>
class LittleEndian {
 public:
  LittleEndian() = default;
  LittleEndian(T v) { set(v); }  // NOLINT(google-explicit-constructor): a field takes an integer
  operator T() const { return get(); }
  LittleEndian& operator=(T v) {
    set(v);
    return *this;
  }

 private:
  T get() const {
    T v;
    memcpy(&v, b_, sizeof v);
    return v;
  }
  void set(T v) { memcpy(b_, &v, sizeof v); }
  uint8_t b_[sizeof(T)];
};

typedef LittleEndian<uint16_t> u16le;
typedef LittleEndian<int16_t> i16le;
typedef LittleEndian<uint32_t> u32le;
typedef LittleEndian<int32_t> i32le;
static_assert(sizeof(u32le) == 4 && alignof(u32le) == 1, "a wire integer is its bytes");

/// Copies n bytes (a message's payload into or out of its struct).
inline void copy(void* to, const void* from, uint8_t n) {
  uint8_t* d = static_cast<uint8_t*>(to);
  const uint8_t* s = static_cast<const uint8_t*>(from);
  for (uint8_t i = 0; i < n; ++i) d[i] = s[i];
}

}  // namespace wire
}  // namespace rovernav
