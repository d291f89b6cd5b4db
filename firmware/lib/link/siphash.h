// SipHash-2-4 (Aumasson and Bernstein, 2012): a keyed 64-bit MAC with a 128-bit key, made for
// short messages. The link's frame tags (issue 14) are built on it; see
// benchmarks/bench_mac.py for its flash and cycles on the Uno against HMAC-SHA256.
#pragma once
#include <stdint.h>

namespace rovernav {

enum : uint8_t { kSipKeyBytes = 16 };

/// SipHash-2-4 of len bytes at data under the 16-byte key; the 64-bit result as its integer
/// (its 8 bytes little-endian are the reference implementation's output bytes).
uint64_t siphash24(const uint8_t* key, const uint8_t* data, uint16_t len);

}  // namespace rovernav
