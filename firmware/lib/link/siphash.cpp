#include "siphash.h"

#include "progmem.h"

namespace rovernav {

namespace {

// "somepseudorandomlygeneratedbytes" as the four initial words, little-endian; each is xored
// with the key's halves k0, k1, k0, k1.
const uint8_t kInit[32] ROVERNAV_PROGMEM = {
    0x75, 0x65, 0x73, 0x70, 0x65, 0x6D, 0x6F, 0x73, 0x6D, 0x6F, 0x64, 0x6E, 0x61, 0x72, 0x6F, 0x64,
    0x61, 0x72, 0x65, 0x6E, 0x65, 0x67, 0x79, 0x6C, 0x73, 0x65, 0x74, 0x79, 0x62, 0x64, 0x65, 0x74};

}  // namespace

#if !defined(__AVR__)
// The round in C++ for every other machine (the AVR's is sip_round_avr.S).
namespace {
uint64_t load64(const uint8_t* p) {
  uint64_t x = 0;
  for (uint8_t i = 8; i > 0; --i) x = (x << 8) | p[i - 1];
  return x;
}
void store64(uint8_t* p, uint64_t x) {
  for (uint8_t i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(x >> (8 * i));
}
uint64_t rotl(uint64_t x, uint8_t b) { return (x << b) | (x >> (64 - b)); }
}  // namespace

extern "C" void rovernav_sip_round(uint8_t* s) {
  uint64_t v0 = load64(s), v1 = load64(s + 8), v2 = load64(s + 16), v3 = load64(s + 24);
  v0 += v1;
  v1 = rotl(v1, 13) ^ v0;
  v0 = rotl(v0, 32);
  v2 += v3;
  v3 = rotl(v3, 16) ^ v2;
  v0 += v3;
  v3 = rotl(v3, 21) ^ v0;
  v2 += v1;
  v1 = rotl(v1, 17) ^ v2;
  v2 = rotl(v2, 32);
  store64(s, v0);
  store64(s + 8, v1);
  store64(s + 16, v2);
  store64(s + 24, v3);
}
#endif

void SipHash24::begin(const uint8_t* key) {
  for (uint8_t i = 0; i < 32; ++i) v_[i] = static_cast<uint8_t>(flash_read_u8(&kInit[i]) ^ key[i & 15]);
  len_ = 0;
}

void SipHash24::absorb() {
  for (uint8_t i = 0; i < 8; ++i) v_[24 + i] ^= m_[i];   // v3 ^= m
  rovernav_sip_round(v_);
  rovernav_sip_round(v_);
  for (uint8_t i = 0; i < 8; ++i) v_[i] ^= m_[i];        // v0 ^= m
}

void SipHash24::update(uint8_t byte) { update(&byte, 1); }

void SipHash24::update(const uint8_t* data, uint8_t len) {
  uint8_t k = len_ & 7;
  len_ = static_cast<uint8_t>(len_ + len);
  for (uint8_t i = 0; i < len; ++i) {
    m_[k] = data[i];
    if (++k == 8) {
      absorb();
      k = 0;
    }
  }
}

void SipHash24::finish(uint8_t* tag) {
  // The last block: what is left, zeros, and the length's low byte on top.
  const uint8_t n = len_;
  for (uint8_t i = n & 7; i < 7; ++i) m_[i] = 0;
  m_[7] = n;
  absorb();
  v_[16] ^= 0xFF;   // v2 ^= 0xff
  for (uint8_t r = 0; r < 4; ++r) rovernav_sip_round(v_);
  for (uint8_t i = 0; i < 8; ++i) tag[i] = static_cast<uint8_t>(v_[i] ^ v_[8 + i] ^ v_[16 + i] ^ v_[24 + i]);
}

void siphash24(const uint8_t* key, const uint8_t* data, uint8_t len, uint8_t* tag) {
  SipHash24 h;
  h.begin(key);
  h.update(data, len);
  h.finish(tag);
}

}  // namespace rovernav
