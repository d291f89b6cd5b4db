// SipHash-2-4 (Aumasson and Bernstein, 2012): a keyed 64-bit MAC with a 128-bit key, made for
// short messages. The link's frame tags (frame_auth.h) are built on it; see
// benchmarks/bench_mac.py for its flash and cycles on the Uno against HMAC-SHA256.
//
// The state is 32 bytes (v0..v3, little-endian) and every step but the round works a byte at a
// time: on the AVR the round is assembly (sip_round_avr.S) and nothing touches 64-bit integers,
// which avr-gcc handles through memory and library loops.
#pragma once
#include <stdint.h>

namespace rovernav {

enum : uint8_t { kSipKeyBytes = 16, kSipTagBytes = 8 };

/// An incremental SipHash-2-4: begin(key), update() as the bytes come, finish() the tag.
class SipHash24 {
 public:
  void begin(const uint8_t* key);
  void update(uint8_t byte);
  void update(const uint8_t* data, uint8_t len);
  /// The 8 bytes of the reference implementation's output (the 64-bit result, little-endian).
  void finish(uint8_t* tag);

 private:
  void absorb();

  uint8_t v_[32];
  uint8_t m_[8];
  uint8_t len_;   // bytes taken, mod 256: all SipHash keeps of the length
};

/// SipHash-2-4 of len bytes at data under the 16-byte key, into tag[0..7].
void siphash24(const uint8_t* key, const uint8_t* data, uint8_t len, uint8_t* tag);

/// One SipRound on the 32-byte state (assembly on the AVR).
extern "C" void rovernav_sip_round(uint8_t* v);

}  // namespace rovernav
