// libFuzzer entry point for the frame decoder and the signature check behind it (clang
// -fsanitize=fuzzer,address,undefined). The input's first byte says whether the receiving end
// holds the key (bit 0; the key is 00 01 .. 0f, which the corpus's signed frames use), the rest
// is the byte stream. Properties checked on every input, beyond "does not crash":
//   * an unsigned frame the decoder accepts re-encodes to exactly the bytes it was read from;
//   * every completed non-empty frame is either accepted or counted under one reason;
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
  rovernav::FrameAuth auth;
  auth.begin((data[0] & 1) ? kKey : nullptr);
  ++data;
  --size;
  rovernav::FrameDecoder dec;
  uint8_t segment[rovernav::kMaxEncodedFrame + 1];
  size_t seg_len = 0;
  uint32_t completed = 0, taken = 0;
  bool seg_overflow = false;
  for (size_t i = 0; i < size; ++i) {
    const uint8_t b = data[i];
    if (seg_len < sizeof segment) segment[seg_len++] = b;
    else seg_overflow = true;
    if (dec.push(b)) {
      const rovernav::Frame& f = dec.frame();
      if (f.signed_len == 0) {
        uint8_t again[rovernav::kMaxEncodedFrame];
        const uint8_t n = rovernav::encode_frame(f.msg_id, f.seq, f.payload, f.payload_len, again);
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
      if (seg_len > 1 || seg_overflow) ++completed;
      seg_len = 0;
      seg_overflow = false;
    }
  }
  const rovernav::FrameCounters& c = dec.counters();
  const uint32_t seen = static_cast<uint32_t>(c.frames_ok) + c.bad_crc + c.overlong + c.unknown_id + c.malformed;
  if (seen != completed) abort();
  const rovernav::AuthCounters& a = auth.counters();
  if (taken + a.bad_tag + a.replayed + a.not_signed + a.unverified != c.frames_ok) abort();
  return 0;
}
