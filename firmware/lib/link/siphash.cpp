#include "siphash.h"

#include <string.h>

#include "progmem.h"

namespace rovernav {

namespace {

inline uint64_t rotl(uint64_t x, uint8_t b) { return (x << b) | (x >> (64 - b)); }

// One SipRound on the state v[0..3]. Out of line: on the AVR each 64-bit addition or rotation
// is a dozen or more instructions, and the rounds run 2 per 8 bytes plus 4 at the end.
// Measured on the Uno (python benchmarks/bench_mac.py). Tried and dropped: the state as byte
// arrays (968 bytes of flash but 2.4-6.5 ms a tag), as 32-bit halves (1,722 bytes, 1.4-3.9 ms),
// and the rotation out of line (smaller by 180 bytes, a third slower).
#if defined(__AVR__)
__attribute__((noinline))
#endif
void sip_round(uint64_t* v) {
  v[0] += v[1];
  v[1] = rotl(v[1], 13);
  v[1] ^= v[0];
  v[0] = rotl(v[0], 32);
  v[2] += v[3];
  v[3] = rotl(v[3], 16);
  v[3] ^= v[2];
  v[0] += v[3];
  v[3] = rotl(v[3], 21);
  v[3] ^= v[0];
  v[2] += v[1];
  v[1] = rotl(v[1], 17);
  v[1] ^= v[2];
  v[2] = rotl(v[2], 32);
}

// Up to 8 little-endian bytes as an integer. On a little-endian machine (the AVR, x86) a copy
// into the low bytes; a shift loop elsewhere (on the AVR each 64-bit shift step is long code).
uint64_t load_le(const uint8_t* p, uint8_t n) {
  uint64_t m = 0;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  memcpy(&m, p, n);
#else
  for (uint8_t i = n; i > 0; --i) m = (m << 8) | p[i - 1];
#endif
  return m;
}

#if defined(__AVR__)
__attribute__((noinline))
#endif
void absorb(uint64_t* v, uint64_t m) {
  v[3] ^= m;
  sip_round(v);
  sip_round(v);
  v[0] ^= m;
}

}  // namespace

uint64_t siphash24(const uint8_t* key, const uint8_t* data, uint16_t len) {
  // "somepseudorandomlygeneratedbytes", xored with the key's halves k0, k1, k0, k1
  static const uint32_t kInit[8] ROVERNAV_PROGMEM = {0x70736575UL, 0x736F6D65UL, 0x6E646F6DUL, 0x646F7261UL,
                                                     0x6E657261UL, 0x6C796765UL, 0x79746573UL, 0x74656462UL};
  uint64_t v[4];
  for (uint8_t i = 0; i < 4; ++i) {
    const uint64_t c = static_cast<uint64_t>(static_cast<uint32_t>(flash_read_i32(reinterpret_cast<const int32_t*>(&kInit[2 * i + 1])))) << 32 |
                       static_cast<uint32_t>(flash_read_i32(reinterpret_cast<const int32_t*>(&kInit[2 * i])));
    v[i] = c ^ load_le(key + 8 * (i & 1), 8);
  }
  const uint16_t whole = static_cast<uint16_t>(len - len % 8);
  for (uint16_t i = 0; i < whole; i = static_cast<uint16_t>(i + 8)) absorb(v, load_le(data + i, 8));
  uint8_t last[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (uint8_t i = 0; i < len - whole; ++i) last[i] = data[whole + i];
  last[7] = static_cast<uint8_t>(len);
  absorb(v, load_le(last, 8));
  v[2] ^= 0xFF;
  for (uint8_t r = 0; r < 4; ++r) sip_round(v);
  return v[0] ^ v[1] ^ v[2] ^ v[3];
}

}  // namespace rovernav
