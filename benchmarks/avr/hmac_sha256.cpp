// HMAC-SHA256 (FIPS 180-4, RFC 2104), written for benchmarks/bench_mac.py only: the rival of
// SipHash-2-4 for the link's frame tags, measured on the Uno. Not used by the firmware.
#include <stdint.h>
#include <string.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define K_READ(i) pgm_read_dword(&kK[i])
#define K_MEM PROGMEM
#else
#define K_READ(i) kK[i]
#define K_MEM
#endif

namespace {

const uint32_t kK[64] K_MEM = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

inline uint32_t ror(uint32_t x, uint8_t n) { return (x >> n) | (x << (32 - n)); }

struct Sha256 {
  uint32_t h[8];
  uint8_t block[64];
  uint8_t used;
  uint32_t total;

  void begin() {
    const uint32_t init[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                              0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    memcpy(h, init, sizeof h);
    used = 0;
    total = 0;
  }
  void compress() {
    uint32_t w[16];
    for (uint8_t i = 0; i < 16; ++i)
      w[i] = (uint32_t)block[4 * i] << 24 | (uint32_t)block[4 * i + 1] << 16 | (uint32_t)block[4 * i + 2] << 8 | block[4 * i + 3];
    uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4], f = h[5], g = h[6], k = h[7];
    for (uint8_t i = 0; i < 64; ++i) {
      if (i >= 16) {   // the message schedule in a 16-word ring
        const uint32_t w15 = w[(i + 1) & 15], w2 = w[(i + 14) & 15];
        w[i & 15] += (ror(w15, 7) ^ ror(w15, 18) ^ (w15 >> 3)) + w[(i + 9) & 15] + (ror(w2, 17) ^ ror(w2, 19) ^ (w2 >> 10));
      }
      const uint32_t t1 = k + (ror(e, 6) ^ ror(e, 11) ^ ror(e, 25)) + ((e & f) ^ (~e & g)) + K_READ(i) + w[i & 15];
      const uint32_t t2 = (ror(a, 2) ^ ror(a, 13) ^ ror(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
      k = g; g = f; f = e; e = d + t1; d = c; c = b; b = a; a = t1 + t2;
    }
    h[0] += a; h[1] += b; h[2] += c; h[3] += d; h[4] += e; h[5] += f; h[6] += g; h[7] += k;
  }
  void update(const uint8_t* p, uint16_t n) {
    for (uint16_t i = 0; i < n; ++i) {
      block[used++] = p[i];
      ++total;
      if (used == 64) { compress(); used = 0; }
    }
  }
  void end(uint8_t* out) {
    const uint32_t bits = total * 8;
    const uint8_t one = 0x80, zero = 0;
    update(&one, 1);
    while (used != 56) update(&zero, 1);
    uint8_t len[8] = {0, 0, 0, 0, (uint8_t)(bits >> 24), (uint8_t)(bits >> 16), (uint8_t)(bits >> 8), (uint8_t)bits};
    update(len, 8);
    for (uint8_t i = 0; i < 8; ++i) {
      out[4 * i] = (uint8_t)(h[i] >> 24); out[4 * i + 1] = (uint8_t)(h[i] >> 16);
      out[4 * i + 2] = (uint8_t)(h[i] >> 8); out[4 * i + 3] = (uint8_t)h[i];
    }
  }
};

}  // namespace

/// HMAC-SHA256 of len bytes under a 16-byte key; the 32-byte tag to out.
void hmac_sha256(const uint8_t* key, const uint8_t* data, uint16_t len, uint8_t* out) {
  uint8_t pad[64];
  Sha256 s;
  memset(pad, 0x36, sizeof pad);
  for (uint8_t i = 0; i < 16; ++i) pad[i] ^= key[i];
  s.begin();
  s.update(pad, 64);
  s.update(data, len);
  uint8_t inner[32];
  s.end(inner);
  for (uint8_t i = 0; i < 64; ++i) pad[i] ^= 0x36 ^ 0x5c;
  s.begin();
  s.update(pad, 64);
  s.update(inner, 32);
  s.end(out);
}
