// libFuzzer entry point for the frame decoder and the signature check behind it (clang
// -fsanitize=fuzzer,address,undefined). The input's first byte says whether the receiving end
// holds the key (bit 0; the key is 00 01 .. 0f, which the corpus's signed frames use) and its
// address in a fleet (bits 1-2, [fleet]), the rest is the byte stream, fed to a decoder at each of
// the four addresses. Properties checked on every input, beyond "does not crash":
//   * an unsigned frame the decoder accepts re-encodes to exactly the bytes it was read from (at
//     the receiving end's address);
//   * every completed non-empty frame is either accepted or counted under one reason by the
//     decoder at its address, and counted at most once by each of the others (another address's
//     frame is dropped uncounted, unless it was already broken);
//   * a decoder accepts only frames of its own address;
//   * every frame the decoder accepts is counted by the signature check under exactly one of
//     taken, bad_tag, replayed, not_signed, unverified;
//   * a signed frame is taken only with a counter above every one taken before, which becomes
//     the last taken; a refused one leaves it as it was; a tag is computed only for a signed
//     frame with a fresh counter, at a keyed end.
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "frame_auth.h"

namespace {
uint64_t as_u64(const rovernav::Counter48& c) {
  uint64_t x = 0;
  for (int i = rovernav::kSignCounterBytes; i > 0; --i) x = (x << 8) | c.b[i - 1];
  return x;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const uint8_t kKey[rovernav::kSipKeyBytes] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  const uint8_t listen = static_cast<uint8_t>((data[0] >> 1) & (rovernav::kMaxRovers - 1));
  rovernav::FrameAuth auth;
  auth.set_address(listen);
  auth.begin((data[0] & 1) ? kKey : nullptr);
  rovernav::FrameAuth plain;   // the same address, no key: how an unsigned frame is written there
  plain.set_address(listen);
  ++data;
  --size;
  rovernav::FrameDecoder decs[rovernav::kMaxRovers];
  rovernav::FrameDecoder& dec = decs[listen];
  uint32_t counted[rovernav::kMaxRovers] = {0, 0, 0, 0};
  uint8_t segment[rovernav::kMaxEncodedFrame + 1];
  size_t seg_len = 0;
  uint32_t completed = 0, taken = 0;
  bool seg_overflow = false;
  for (size_t i = 0; i < size; ++i) {
    const uint8_t b = data[i];
    if (seg_len < sizeof segment) segment[seg_len++] = b;
    else seg_overflow = true;
    for (uint8_t a = 0; a < rovernav::kMaxRovers; ++a) {
      if (a != listen && decs[a].push(b, static_cast<uint8_t>(a << rovernav::kAddressShift)) &&
          (decs[a].frame().version & rovernav::kAddressMask) != (a << rovernav::kAddressShift)) {
        abort();
      }
    }
    if (dec.push(b, auth.address_bits())) {
      const rovernav::Frame& f = dec.frame();
      if ((f.version & rovernav::kAddressMask) != auth.address_bits()) abort();
      if (f.signed_len == 0) {
        uint8_t again[rovernav::kMaxEncodedFrame];
        const uint8_t n = rovernav::encode_frame(f.msg_id, f.seq, f.payload, f.payload_len, again, &plain);
        if (seg_overflow || n != seg_len || memcmp(again, segment, n) != 0) abort();
      } else if (f.signed_len != rovernav::kFrameHeader + f.payload_len + rovernav::kSignCounterBytes) {
        abort();
      }
      const uint64_t before = as_u64(auth.rx_last());
      const rovernav::AuthResult r = auth.check(f);
      const uint64_t after = as_u64(auth.rx_last());
      const bool accepted = r == rovernav::AuthResult::Accepted || r == rovernav::AuthResult::AcceptedAfterTag;
      const bool tagged = r == rovernav::AuthResult::AcceptedAfterTag || r == rovernav::AuthResult::RefusedAfterTag;
      if (accepted) ++taken;
      if (tagged && (!auth.keyed() || f.signed_len == 0)) abort();
      if (r == rovernav::AuthResult::AcceptedAfterTag) {
        const uint64_t c = as_u64(rovernav::counter_at(f.counter()));
        if (!(c > before) || after != c) abort();
      } else if (after != before) {
        abort();
      }
      if (auth.keyed() && f.signed_len == 0 && accepted && !rovernav::may_be_unsigned(f.msg_id)) abort();
      if (!auth.keyed() && f.signed_len != 0 && accepted) abort();
    }
    if (b == 0) {
      if (seg_len > 1 || seg_overflow) {
        ++completed;
        // Counted once by the decoder at the frame's address, at most once by each other one.
        uint32_t by = 0;
        for (uint8_t a = 0; a < rovernav::kMaxRovers; ++a) {
          const rovernav::FrameCounters& k = decs[a].counters();
          const uint32_t now = static_cast<uint32_t>(k.frames_ok) + k.bad_crc + k.overlong + k.unknown_id + k.malformed;
          if (now - counted[a] > 1) abort();
          by += now - counted[a];
          counted[a] = now;
        }
        if (by == 0) abort();
      }
      seg_len = 0;
      seg_overflow = false;
    }
  }
  const rovernav::FrameCounters& c = dec.counters();
  const rovernav::AuthCounters& a = auth.counters();
  if (taken + a.bad_tag + a.replayed + a.not_signed + a.unverified != c.frames_ok) abort();
  return 0;
}
