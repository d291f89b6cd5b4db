// Behaviour of the frame decoder on streams that are not clean: garbage, truncation,
// bit flips, random bytes. Randomness is a fixed-seed xorshift, so failures repeat.
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "frame.h"
#include "test_streams.h"

using rovernav::FrameDecoder;

#include "vectors_gen.h"  // the golden tables only

TEST_CASE("decoder accepts every golden frame fed one byte at a time, with delimiters between") {
  FrameDecoder dec;
  int got = 0;
  for (const GoldenFrame& g : kGoldenFrames) {
    dec.push(0x00);  // a stray delimiter is not a frame and is not counted
    for (uint8_t i = 0; i < g.len; ++i) got += dec.push(g.bytes[i]) ? 1 : 0;
  }
  const int n = static_cast<int>(sizeof kGoldenFrames / sizeof kGoldenFrames[0]);
  CHECK(got == n);
  CHECK(dec.counters().frames_ok == n);
  CHECK(dec.counters().malformed == 0);
}

TEST_CASE("decoder drops garbage and resynchronises at the next delimiter") {
  FrameDecoder dec;
  const uint8_t garbage[] = {0x13, 0x37, 0xFF, 0x01, 0x02, 0x42};
  for (uint8_t b : garbage) CHECK_FALSE(dec.push(b));
  CHECK_FALSE(dec.push(0x00));  // ends the garbage "frame"
  const GoldenFrame& g = kGoldenFrames[0];
  bool ok = false;
  for (uint8_t i = 0; i < g.len; ++i) ok = dec.push(g.bytes[i]) || ok;
  CHECK(ok);
  const rovernav::FrameCounters& c = dec.counters();
  CHECK(c.frames_ok == 1);
  CHECK(c.bad_crc + c.malformed + c.unknown_id + c.overlong == 1);
}

TEST_CASE("every single-bit flip of every golden frame is rejected and counted") {
  // Failures are counted and asserted once, with the first one named: a passing run stays a few
  // lines long under `pio test`'s success reporting (test_doctest_output.py checks that).
  long flips = 0, taken = 0, uncounted = 0;
  int first_len = -1, first_pos = -1, first_bit = -1;
  for (const GoldenFrame& g : kGoldenFrames) {
    for (uint8_t pos = 0; pos < g.len; ++pos) {
      for (uint8_t bit = 0; bit < 8; ++bit) {
        uint8_t copy[rovernav::kMaxEncodedFrame + 1];
        memcpy(copy, g.bytes, g.len);
        copy[pos] = static_cast<uint8_t>(copy[pos] ^ (1u << bit));
        FrameDecoder dec;
        bool any = false;
        for (uint8_t i = 0; i < g.len; ++i) any = dec.push(copy[i]) || any;
        any = dec.push(0x00) || any;  // terminate whatever the flip left open
        const rovernav::FrameCounters& c = dec.counters();
        const bool counted = c.bad_crc + c.malformed + c.unknown_id + c.overlong >= 1;
        if ((any || !counted) && first_len < 0) {
          first_len = g.len;
          first_pos = pos;
          first_bit = bit;
        }
        taken += any ? 1 : 0;
        uncounted += counted ? 0 : 1;
        ++flips;
      }
    }
  }
  CAPTURE(first_len);
  CAPTURE(first_pos);
  CAPTURE(first_bit);
  CHECK(taken == 0);
  CHECK(uncounted == 0);
  MESSAGE("bit flips tried: " << flips);
}

TEST_CASE("every truncation of every golden frame is rejected") {
  long tried = 0, taken = 0;
  for (const GoldenFrame& g : kGoldenFrames) {
    for (uint8_t keep = 1; keep + 1 < g.len; ++keep) {
      FrameDecoder dec;
      bool any = false;
      for (uint8_t i = 0; i < keep; ++i) any = dec.push(g.bytes[i]) || any;
      any = dec.push(0x00) || any;
      taken += (any || dec.counters().frames_ok != 0) ? 1 : 0;
      ++tried;
    }
  }
  CHECK(tried > 300);
  CHECK(taken == 0);
}

TEST_CASE("random bytes never crash the decoder and never yield a frame that re-encodes differently") {
  rovernav::test::XorShift rng(0x2545F491u);
  FrameDecoder dec;
  uint8_t segment[rovernav::kMaxEncodedFrame + 1];
  uint8_t seg_len = 0;
  long accepted = 0;
  for (long i = 0; i < 2000000L; ++i) {
    // Mostly small alphabets so that delimiters and short frames are common.
    const uint8_t b = static_cast<uint8_t>(rng.next() % 8 == 0 ? 0 : rng.next());
    if (seg_len < sizeof segment) segment[seg_len++] = b;
    if (dec.push(b)) {
      ++accepted;
      const rovernav::Frame& f = dec.frame();
      uint8_t again[rovernav::kMaxEncodedFrame];
      const uint8_t n = rovernav::encode_frame(f.msg_id, f.seq, f.payload, f.payload_len, again);
      REQUIRE(n == seg_len);
      CHECK(memcmp(again, segment, n) == 0);
    }
    if (b == 0) seg_len = 0;
  }
  MESSAGE("random frames accepted (must be rare): " << accepted);
  const rovernav::FrameCounters& c = dec.counters();
  CHECK(c.bad_crc + c.malformed + c.unknown_id + c.overlong > 1000);
}

TEST_CASE("frames hidden in a noisy stream are all recovered when delimited") {
  rovernav::test::XorShift rng(12345u);
  FrameDecoder dec;
  const int n_golden = static_cast<int>(sizeof kGoldenFrames / sizeof kGoldenFrames[0]);
  int sent = 0, got = 0;
  for (int round = 0; round < 5000; ++round) {
    const uint32_t noise = rng.next() % 80;
    for (uint32_t i = 0; i < noise; ++i) got += dec.push(static_cast<uint8_t>(rng.next())) ? 1 : 0;
    got += dec.push(0x00) ? 1 : 0;
    const GoldenFrame& g = kGoldenFrames[rng.next() % static_cast<uint32_t>(n_golden)];
    for (uint8_t i = 0; i < g.len; ++i) got += dec.push(g.bytes[i]) ? 1 : 0;
    ++sent;
  }
  // Noise can by chance form a valid frame, at odds of about 2^-16 per noise segment.
  CHECK(got >= sent);
  CHECK(got <= sent + 2);
}

TEST_CASE("encode_frame refuses a payload longer than a frame can carry") {
  uint8_t payload[rovernav::kMaxPayload + 1] = {};
  uint8_t out[rovernav::kMaxEncodedFrame];
  CHECK(rovernav::encode_frame(0x01, 0, payload, rovernav::kMaxPayload + 1, out) == 0);
  // the longest unsigned frame: its raw bytes, a COBS code byte and the delimiter
  CHECK(rovernav::encode_frame(0x01, 0, payload, rovernav::kMaxPayload, out) == rovernav::kMaxRawFrame + 2);
}

TEST_CASE("every encoded frame has no zero byte before its delimiter") {
  rovernav::test::XorShift rng(99u);
  long wrong_length = 0, zeros = 0, undelimited = 0;   // counted, asserted once (short success output)
  for (int round = 0; round < 20000; ++round) {
    uint8_t payload[rovernav::kMaxPayload];
    const uint8_t len = static_cast<uint8_t>(rng.next() % (rovernav::kMaxPayload + 1));
    for (uint8_t i = 0; i < len; ++i) payload[i] = static_cast<uint8_t>(rng.next() % 3 == 0 ? 0 : rng.next());
    uint8_t out[rovernav::kMaxEncodedFrame];
    const uint8_t n = rovernav::encode_frame(static_cast<uint8_t>(rng.next()), static_cast<uint8_t>(round), payload, len, out);
    if (n != len + 3 + 2 + 2) ++wrong_length;
    for (uint8_t i = 0; i + 1 < n; ++i) zeros += out[i] == 0 ? 1 : 0;
    if (out[n - 1] != 0) ++undelimited;
  }
  CHECK(wrong_length == 0);
  CHECK(zeros == 0);
  CHECK(undelimited == 0);
}
