// The golden vectors of protocol/vectors.json, shared with the Python tests: our encoder
// must produce them byte for byte and our decoder must read them back field for field.
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "frame.h"

namespace {

template <typename Msg>
void check_golden_encode(const Msg& m, uint8_t seq, const uint8_t* frame, size_t len) {
  uint8_t out[rovernav::kMaxEncodedFrame];
  const uint8_t n = rovernav::encode_message(m, seq, out);
  REQUIRE(n == len);
  CHECK(memcmp(out, frame, len) == 0);
}

template <typename Msg>
Msg decode_golden(const uint8_t* frame, size_t len, uint8_t seq) {
  rovernav::FrameDecoder dec;
  int frames = 0;
  Msg m{};
  for (size_t i = 0; i < len; ++i) {
    if (dec.push(frame[i])) {
      ++frames;
      CHECK(dec.frame().seq == seq);
      CHECK(rovernav::decode_message(dec.frame(), m));
    }
  }
  CHECK(frames == 1);
  CHECK(dec.counters().frames_ok == 1);
  return m;
}

}  // namespace

#define ROVERNAV_GOLDEN_TEST_CASES
#include "vectors_gen.h"

TEST_CASE("CRC-16/CCITT-FALSE gives the catalogue check value 0x29B1 for \"123456789\"") {
  const uint8_t text[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  CHECK(rovernav::crc16_ccitt_false(text, sizeof text) == 0x29B1);
}

TEST_CASE("every bad golden frame is dropped and counted under its reason") {
  for (const BadFrame& bad : kBadFrames) {
    CAPTURE(bad.name);
    rovernav::FrameDecoder dec;
    bool any = false;
    for (uint8_t i = 0; i < bad.len; ++i) any = dec.push(bad.bytes[i]) || any;
    CHECK_FALSE(any);
    const rovernav::FrameCounters& c = dec.counters();
    const uint16_t dropped = static_cast<uint16_t>(c.bad_crc + c.overlong + c.unknown_id + c.malformed);
    CHECK(dropped == 1);
    const char* counter = bad.counter;
    if (strcmp(counter, "bad_crc") == 0) CHECK(c.bad_crc == 1);
    else if (strcmp(counter, "overlong") == 0) CHECK(c.overlong == 1);
    else if (strcmp(counter, "unknown_id") == 0) CHECK(c.unknown_id == 1);
    else if (strcmp(counter, "malformed") == 0) CHECK(c.malformed == 1);
    else FAIL("vectors name an unknown counter: " << counter);
  }
}
