// The signed-frame golden vectors of protocol/vectors.json (kSignedVectors, vectors_gen.h),
// computed by generate.py's reference encoder and shared with the Python tests: the rover's
// FrameAuth verifies each host-to-rover frame and signs each rover-to-host one byte for byte;
// the tag of every one is SipHash-2-4 of its direction byte and version..counter.
#include <doctest.h>
#include <string.h>

#include "frame.h"
#include "frame_auth.h"
#include "vectors_gen.h"

using namespace rovernav;

namespace {

uint64_t counter_value(const uint8_t* c) {
  uint64_t x = 0;
  for (int i = kSignCounterBytes; i > 0; --i) x = (x << 8) | c[i - 1];
  return x;
}

Counter48 counter_of(uint64_t x) {
  Counter48 c;
  for (int i = 0; i < kSignCounterBytes; ++i) c.b[i] = static_cast<uint8_t>(x >> (8 * i));
  return c;
}

/// The counters to resume from so that the last one is `last` (resume() adds the reset margin).
Counter48 stored_for(uint64_t last) {
  REQUIRE(last >= kSignResetMargin);
  return counter_of(last - kSignResetMargin);
}

/// The vector's frame, decoded (it must be exactly one well-formed signed frame).
struct Decoded {
  FrameDecoder dec;
  explicit Decoded(const SignedVector& v) {
    int frames = 0;
    for (uint8_t i = 0; i < v.wire_len; ++i) frames += dec.push(v.wire[i]) ? 1 : 0;
    REQUIRE(frames == 1);
  }
  const Frame& frame() const { return dec.frame(); }
};

}  // namespace

TEST_CASE("signed vectors: both directions, a HELLO, a max_payload frame and counters past 2^32 and to 2^48 - 1") {
  bool dir[3] = {false, false, false};
  bool hello[3] = {false, false, false};
  bool max_payload = false, past_2_32[3] = {false, false, false}, last_counter = false;
  for (const SignedVector& v : kSignedVectors) {
    REQUIRE((v.direction == kSignHostToRover || v.direction == kSignRoverToHost));
    dir[v.direction] = true;
    if (v.msg_id == msg::Hello::kId) hello[v.direction] = true;
    const Decoded d(v);
    if (d.frame().payload_len == kMaxPayload) max_payload = true;
    const uint64_t c = counter_value(v.counter);
    if (c > 0xFFFFFFFFull) past_2_32[v.direction] = true;
    if (c == 0xFFFFFFFFFFFFull) last_counter = true;
  }
  CHECK((dir[kSignHostToRover] && dir[kSignRoverToHost]));
  CHECK((hello[kSignHostToRover] && hello[kSignRoverToHost]));
  CHECK((past_2_32[kSignHostToRover] && past_2_32[kSignRoverToHost]));
  CHECK(max_payload);
  CHECK(last_counter);
}

TEST_CASE("signed vectors: each tag is SipHash-2-4 of the direction byte and version..counter, as the frame carries it") {
  for (const SignedVector& v : kSignedVectors) {
    CAPTURE(v.name);
    const Decoded d(v);
    const Frame& f = d.frame();
    REQUIRE(f.signed_len == v.mac_input_len - 1);
    CHECK(f.msg_id == v.msg_id);
    CHECK(v.mac_input[0] == v.direction);
    CHECK(memcmp(f.signed_part(), v.mac_input + 1, f.signed_len) == 0);
    CHECK(memcmp(f.counter(), v.counter, kSignCounterBytes) == 0);
    CHECK(memcmp(f.tag(), v.tag, kSignTagBytes) == 0);
    SipHash24 h;
    h.begin(v.key);
    h.update(v.mac_input, v.mac_input_len);
    uint8_t tag[kSipTagBytes];
    h.finish(tag);
    CHECK(memcmp(tag, v.tag, kSignTagBytes) == 0);
  }
}

TEST_CASE("signed vectors: the rover's FrameAuth takes each host frame once, at its counter, and only with its key") {
  int checked = 0;
  for (const SignedVector& v : kSignedVectors) {
    if (v.direction != kSignHostToRover) continue;
    CAPTURE(v.name);
    const Decoded d(v);
    const uint64_t c = counter_value(v.counter);
    FrameAuth auth;
    auth.begin(v.key);
    auth.resume(Counter48{}, stored_for(c - 1));   // the last host counter taken: one below the vector's
    CHECK(auth.check(d.frame()) == AuthResult::AcceptedAfterTag);
    CHECK(counter_value(auth.rx_last().b) == c);
    CHECK(auth.check(d.frame()) == AuthResult::Refused);   // the same counter again: replayed
    CHECK(auth.counters().replayed == 1);

    uint8_t other[kSipKeyBytes];
    memcpy(other, v.key, sizeof other);
    other[15] ^= 0x80;
    FrameAuth stranger;
    stranger.begin(other);
    stranger.resume(Counter48{}, stored_for(c - 1));
    CHECK(stranger.check(d.frame()) == AuthResult::RefusedAfterTag);
    CHECK(stranger.counters().bad_tag == 1);
    ++checked;
  }
  CHECK(checked >= 3);
}

TEST_CASE("signed vectors: the rover's FrameAuth signs each rover frame byte for byte") {
  int checked = 0;
  for (const SignedVector& v : kSignedVectors) {
    if (v.direction != kSignRoverToHost) continue;
    CAPTURE(v.name);
    const Decoded d(v);
    const Frame& f = d.frame();
    FrameAuth auth;
    auth.begin(v.key);
    auth.resume(stored_for(counter_value(v.counter) - 1), Counter48{});   // its next frame takes the vector's counter
    uint8_t payload[kMaxPayload];
    memcpy(payload, f.payload, f.payload_len);
    uint8_t out[kMaxEncodedFrame];
    const uint8_t n = encode_frame(f.msg_id, f.seq, payload, f.payload_len, out, &auth);
    REQUIRE(n == v.wire_len);
    CHECK(memcmp(out, v.wire, n) == 0);
    CHECK(memcmp(auth.tx_last().b, v.counter, kSignCounterBytes) == 0);
    ++checked;
  }
  CHECK(checked >= 2);
}
