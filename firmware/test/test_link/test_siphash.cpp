// SipHash-2-4 against the reference vectors of Aumasson and Bernstein's paper (key 00..0f,
// message 00..len-1), and against host/rovernav/link/siphash.py on longer and odd lengths.
#include <doctest.h>

#include "siphash.h"

using namespace rovernav;

namespace {
uint64_t as_u64(const uint8_t* tag) {
  uint64_t x = 0;
  for (uint8_t i = 8; i > 0; --i) x = (x << 8) | tag[i - 1];
  return x;
}
uint64_t siphash_u64(const uint8_t* key, const uint8_t* msg, uint8_t len) {
  uint8_t tag[8];
  siphash24(key, msg, len, tag);
  return as_u64(tag);
}
uint64_t of_counting_bytes(uint8_t len) {
  uint8_t key[16], msg[64];
  for (uint8_t i = 0; i < 16; ++i) key[i] = i;
  for (uint8_t i = 0; i < 64; ++i) msg[i] = i;
  return siphash_u64(key, msg, len);
}
}  // namespace

TEST_CASE("SipHash-2-4 gives the paper's reference outputs") {
  CHECK(of_counting_bytes(0) == 0x726FDB47DD0E0E31ULL);
  CHECK(of_counting_bytes(15) == 0xA129CA6149BE45E5ULL);
}

TEST_CASE("SipHash-2-4 agrees with the host's implementation at every block boundary") {
  // host/rovernav/link/siphash.py, same key and messages (tests/test_siphash.py checks these too)
  CHECK(of_counting_bytes(7) == 0xAB0200F58B01D137ULL);
  CHECK(of_counting_bytes(8) == 0x93F5F5799A932462ULL);
  CHECK(of_counting_bytes(9) == 0x9E0082DF0BA9E4B0ULL);
  CHECK(of_counting_bytes(16) == 0x3F2ACC7F57C29BDBULL);
  CHECK(of_counting_bytes(63) == 0x958A324CEB064572ULL);
}

TEST_CASE("a one-bit change in key or message changes the tag") {
  uint8_t key[16] = {0}, msg[20] = {0};
  const uint64_t base = siphash_u64(key, msg, sizeof msg);
  msg[19] ^= 0x80;
  CHECK(siphash_u64(key, msg, sizeof msg) != base);
  msg[19] ^= 0x80;
  key[0] ^= 1;
  CHECK(siphash_u64(key, msg, sizeof msg) != base);
}

TEST_CASE("fed in pieces of any size, SipHash-2-4 gives the same tag as in one piece") {
  uint8_t key[16], msg[64];
  for (uint8_t i = 0; i < 16; ++i) key[i] = i;
  for (uint8_t i = 0; i < 64; ++i) msg[i] = i;
  int wrong = 0;
  for (uint8_t len = 0; len <= 64; ++len) {
    for (uint8_t piece = 1; piece <= 9; ++piece) {
      SipHash24 h;
      h.begin(key);
      for (uint8_t at = 0; at < len; at = static_cast<uint8_t>(at + piece)) {
        const uint8_t n = static_cast<uint8_t>(len - at < piece ? len - at : piece);
        if (n == 1) {
          h.update(msg[at]);
        } else {
          h.update(msg + at, n);
        }
      }
      uint8_t tag[8];
      h.finish(tag);
      if (as_u64(tag) != of_counting_bytes(len)) ++wrong;
    }
  }
  CHECK(wrong == 0);   // 585 ways, asserted once
}
