// FrameAuth (frame_auth.h) on its own: 48-bit counters as bytes, the order of the checks, what a
// refusal leaves unchanged, and that a frame it signs is one the host's side takes.
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "frame.h"
#include "frame_auth.h"

using namespace rovernav;

namespace {
const uint8_t kKey[16] = {7, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};

uint64_t as_u64(const Counter48& c) {
  uint64_t x = 0;
  for (int i = kSignCounterBytes; i > 0; --i) x = (x << 8) | c.b[i - 1];
  return x;
}
Counter48 of_u64(uint64_t x) {
  Counter48 c;
  for (int i = 0; i < kSignCounterBytes; ++i) c.b[i] = static_cast<uint8_t>(x >> (8 * i));
  return c;
}

// A host frame (direction kSignHostToRover) with counter c under key k, decoded.
struct HostFrame {
  uint8_t wire[kMaxEncodedFrame];
  uint8_t n;
  FrameDecoder dec;
  const Frame& frame() const { return dec.frame(); }
  HostFrame(const uint8_t* k, uint64_t c, uint8_t msg_id = msg::Stop::kId) {
    // Build the signed raw frame by hand: the tag as frame_tag() on the host computes it.
    uint8_t raw[kMaxSignedRawFrame];
    uint8_t len = 0;
    raw[len++] = static_cast<uint8_t>(kProtocolVersion | kSignFlag);
    raw[len++] = msg_id;
    raw[len++] = 3;
    raw[len++] = 1;   // STOP's reason
    for (int i = 0; i < kSignCounterBytes; ++i) raw[len++] = static_cast<uint8_t>(c >> (8 * i));
    SipHash24 h;
    h.begin(k);
    h.update(kSignHostToRover);
    h.update(raw, len);
    uint8_t tag[8];
    h.finish(tag);
    for (int i = 0; i < kSignTagBytes; ++i) raw[len++] = tag[i];
    // The CRC, then COBS written out here: encode_frame signs only as the rover (direction 2).
    const uint16_t crc = crc16_ccitt_false(raw, len);
    raw[len++] = static_cast<uint8_t>(crc);
    raw[len++] = static_cast<uint8_t>(crc >> 8);
    uint8_t code_pos = 0, w = 1;
    for (uint8_t r = 0; r < len; ++r) {
      if (raw[r] == 0) {
        wire[code_pos] = static_cast<uint8_t>(w - code_pos);
        code_pos = w++;
      } else {
        wire[w++] = raw[r];
      }
    }
    wire[code_pos] = static_cast<uint8_t>(w - code_pos);
    wire[w++] = 0;
    n = w;
    bool done = false;
    for (uint8_t i = 0; i < n; ++i) done = dec.push(wire[i]);
    REQUIRE(done);
  }
};
}  // namespace

TEST_CASE("48-bit counters: addition carries through every byte and wraps at 2^48") {
  CHECK(as_u64(counter_plus(of_u64(0xFFFFFFFFFFULL), 1)) == 0x10000000000ULL);
  CHECK(as_u64(counter_plus(of_u64(0xFFFFFFFFFFFFULL), 2)) == 1);
  CHECK(as_u64(counter_plus(of_u64(5), 0xFFFFFFFFUL)) == 0x100000004ULL);
  CHECK(counter_above(of_u64(0x010000000000ULL), of_u64(0x00FFFFFFFFFFULL)));
  CHECK_FALSE(counter_above(of_u64(7), of_u64(7)));
  CHECK_FALSE(counter_above(of_u64(6), of_u64(7)));
}

TEST_CASE("a keyed end takes a good frame once, refuses a replay before computing a tag, and a wrong tag") {
  FrameAuth auth;
  auth.begin(kKey);
  HostFrame good(kKey, 1000);
  CHECK(auth.check(good.frame()) == AuthResult::AcceptedAfterTag);
  CHECK(as_u64(auth.rx_last()) == 1000);
  CHECK(auth.check(good.frame()) == AuthResult::Refused);   // replayed: no tag computed
  HostFrame older(kKey, 999);
  CHECK(auth.check(older.frame()) == AuthResult::Refused);
  uint8_t other[16];
  memcpy(other, kKey, 16);
  other[15] ^= 1;
  HostFrame forged(other, 5000);
  CHECK(auth.check(forged.frame()) == AuthResult::RefusedAfterTag);
  CHECK(as_u64(auth.rx_last()) == 1000);                     // a refusal moves nothing
  CHECK(auth.counters().replayed == 2);
  CHECK(auth.counters().bad_tag == 1);
  HostFrame next(kKey, 1001);
  CHECK(auth.check(next.frame()) == AuthResult::AcceptedAfterTag);
}

TEST_CASE("after a reset the counters resume past the stored ones by the margin") {
  FrameAuth auth;
  auth.begin(kKey);
  auth.resume(of_u64(10), of_u64(2000));
  CHECK(as_u64(auth.rx_last()) == 2000 + kSignResetMargin);
  HostFrame old(kKey, 2000 + kSignResetMargin);
  CHECK(auth.check(old.frame()) == AuthResult::Refused);
  uint8_t raw[kMaxSignedRawFrame] = {static_cast<uint8_t>(kProtocolVersion | kSignFlag), msg::Ack::kId, 0, 1, 2};
  CHECK(auth.sign(raw, 5) == 5 + kFrameSignature);
  CHECK(as_u64(auth.tx_last()) == 10 + kSignResetMargin + 1);
}

TEST_CASE("an end with no key takes unsigned frames and refuses signed ones as unverified") {
  FrameAuth auth;
  auth.begin(nullptr);
  HostFrame signed_frame(kKey, 1);
  CHECK(auth.check(signed_frame.frame()) == AuthResult::Refused);
  CHECK(auth.counters().unverified == 1);
  uint8_t wire[kMaxEncodedFrame];
  const uint8_t payload[1] = {1};
  const uint8_t n = encode_frame(msg::Stop::kId, 0, payload, 1, wire);
  FrameDecoder dec;
  bool done = false;
  for (uint8_t i = 0; i < n; ++i) done = dec.push(wire[i]);
  REQUIRE(done);
  CHECK(auth.check(dec.frame()) == AuthResult::Accepted);
}
