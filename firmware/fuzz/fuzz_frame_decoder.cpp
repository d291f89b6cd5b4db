// libFuzzer entry point for the frame decoder (clang -fsanitize=fuzzer,address,undefined).
// Properties checked on every input, beyond "does not crash":
//   * a frame the decoder accepts re-encodes to exactly the bytes it was read from;
//   * every completed non-empty frame is either accepted or counted under one reason.
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rovernav::FrameDecoder dec;
  uint8_t segment[rovernav::kMaxEncodedFrame + 1];
  size_t seg_len = 0;
  uint32_t completed = 0;
  bool seg_overflow = false;
  for (size_t i = 0; i < size; ++i) {
    const uint8_t b = data[i];
    if (seg_len < sizeof segment) segment[seg_len++] = b;
    else seg_overflow = true;
    if (dec.push(b)) {
      const rovernav::Frame& f = dec.frame();
      uint8_t again[rovernav::kMaxEncodedFrame];
      const uint8_t n = rovernav::encode_frame(f.msg_id, f.seq, f.payload, f.payload_len, again);
      if (seg_overflow || n != seg_len || memcmp(again, segment, n) != 0) abort();
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
  return 0;
}
