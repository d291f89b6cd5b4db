// A fleet's addresses ([fleet] in protocol/messages.toml): bits kAddressShift.. of the version
// byte. The decoder takes the frames of its own address and drops the others' after the CRC and
// the version, before anything reads their id or checks their tag, counting nothing; an end's
// FrameAuth writes its address into every frame it sends. The vectors (vectors.json
// addressed_frames) come from generate.py's reference encoder; address 0 is a lone rover's, whose
// frames are the golden frames as they were (test_golden.cpp).
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "frame.h"
#include "frame_auth.h"
#include "vectors_gen.h"

using namespace rovernav;

namespace {

uint8_t bits(uint8_t address) { return static_cast<uint8_t>(address << kAddressShift); }

/// Feeds the vector's bytes to a decoder listening at `address`; returns the frames it completed.
int feed(FrameDecoder& dec, const AddressedVector& v, uint8_t address) {
  int frames = 0;
  for (uint8_t i = 0; i < v.wire_len; ++i) frames += dec.push(v.wire[i], bits(address)) ? 1 : 0;
  return frames;
}

uint16_t dropped(const FrameCounters& c) { return static_cast<uint16_t>(c.bad_crc + c.overlong + c.unknown_id + c.malformed); }

}  // namespace

TEST_CASE("the [fleet] constants: four addresses in bits 5-6, apart from the version's bits and the signing flag") {
  CHECK(kMaxRovers == 4);
  CHECK(kAddressShift == 5);
  CHECK(kAddressMask == 0x60);
  CHECK(kVersionMask == 0x1F);
  CHECK((kAddressMask & kSignFlag) == 0);
  CHECK((kAddressMask & kProtocolVersion) == 0);
  CHECK(static_cast<int>(kGrantBytes) >= static_cast<int>(kMaxEncodedFrame));   // the largest frame fits one grant
  CHECK(kGrantBytes == 128);
  CHECK(kGrantMs == 20);
}

TEST_CASE("addressed vectors: the decoder at the frame's address takes it, at every other address drops it uncounted") {
  int vectors = 0;
  for (const AddressedVector& v : kAddressedVectors) {
    CAPTURE(v.name);
    REQUIRE(v.address < kMaxRovers);
    ++vectors;
    FrameDecoder own;
    REQUIRE(feed(own, v, v.address) == 1);
    CHECK(own.frame().msg_id == v.msg_id);
    CHECK((own.frame().version & kAddressMask) == bits(v.address));
    CHECK((own.frame().version & kVersionMask) == kProtocolVersion);
    CHECK((own.frame().signed_len != 0) == v.is_signed);
    CHECK(own.counters().frames_ok == 1);
    for (uint8_t other = 0; other < kMaxRovers; ++other) {
      if (other == v.address) continue;
      CAPTURE(other);
      FrameDecoder dec;
      CHECK(feed(dec, v, other) == 0);
      CHECK(dec.counters().frames_ok == 0);
      CHECK(dropped(dec.counters()) == 0);   // someone else's frame: not a fault of the link
      // ... and the decoder is back in step for the next frame, of its own address
      FrameDecoder again;
      feed(again, v, other);
      uint8_t out[kMaxEncodedFrame];
      const uint8_t payload[2] = {msg::Stop::kId, 0};
      FrameAuth mine;
      mine.set_address(other);
      const uint8_t n = encode_frame(msg::Ack::kId, 3, payload, 2, out, &mine);
      int took = 0;
      for (uint8_t i = 0; i < n; ++i) took += again.push(out[i], bits(other)) ? 1 : 0;
      CHECK(took == 1);
    }
  }
  CHECK(vectors >= 4);
}

TEST_CASE("addressed vectors: a rover at the frame's address sends each rover frame byte for byte, signed or not") {
  int checked = 0;
  for (const AddressedVector& v : kAddressedVectors) {
    if (v.direction != kSignRoverToHost) continue;
    CAPTURE(v.name);
    FrameDecoder own;
    REQUIRE(feed(own, v, v.address) == 1);
    const Frame& f = own.frame();
    FrameAuth auth;
    auth.set_address(v.address);
    if (v.is_signed) {
      auth.begin(v.key);
      uint64_t c = 0;
      for (int i = kSignCounterBytes; i > 0; --i) c = (c << 8) | v.counter[i - 1];
      Counter48 stored{};
      const uint64_t before = c - 1 - kSignResetMargin;   // resume() adds the margin: the next frame takes c
      for (int i = 0; i < kSignCounterBytes; ++i) stored.b[i] = static_cast<uint8_t>(before >> (8 * i));
      auth.resume(stored, Counter48{});
    }
    CHECK(auth.address_bits() == bits(v.address));
    CHECK(auth.version_byte() == (kProtocolVersion | bits(v.address) | (v.is_signed ? kSignFlag : 0)));
    uint8_t payload[kMaxPayload];
    memcpy(payload, f.payload, f.payload_len);
    uint8_t out[kMaxEncodedFrame];
    const uint8_t n = encode_frame(f.msg_id, f.seq, payload, f.payload_len, out, &auth);
    REQUIRE(n == v.wire_len);
    CHECK(memcmp(out, v.wire, n) == 0);
    ++checked;
  }
  CHECK(checked >= 2);
}

TEST_CASE("another rover's signed frame never reaches the tag check: dropped by the decoder, whatever its key") {
  for (const AddressedVector& v : kAddressedVectors) {
    if (v.direction != kSignHostToRover || !v.is_signed) continue;
    CAPTURE(v.name);
    uint8_t stranger[kSipKeyBytes];
    memcpy(stranger, v.key, sizeof stranger);
    stranger[0] ^= 0x01;
    for (uint8_t listen = 0; listen < kMaxRovers; ++listen) {
      CAPTURE(listen);
      FrameAuth auth;
      auth.begin(stranger);
      auth.set_address(listen);
      FrameDecoder dec;
      for (uint8_t i = 0; i < v.wire_len; ++i) {
        if (dec.push(v.wire[i], auth.address_bits())) auth.check(dec.frame());
      }
      // At its own address the frame is checked, and its tag (under another key) refused; at
      // any other, nothing is checked at all.
      CHECK(auth.counters().bad_tag == (listen == v.address ? 1 : 0));
    }
  }
}

TEST_CASE("the version's bits are checked before the address: another version at any address is malformed") {
  for (uint8_t address = 0; address < kMaxRovers; ++address) {
    CAPTURE(address);
    uint8_t raw[16] = {static_cast<uint8_t>((kProtocolVersion + 1) | bits(address)), msg::Stop::kId, 0, 0};
    uint8_t n = 4;
    const uint16_t crc = crc16_ccitt_false(raw, n);
    raw[n++] = static_cast<uint8_t>(crc);
    raw[n++] = static_cast<uint8_t>(crc >> 8);
    uint8_t wire[24];
    uint8_t code = 0, w = 1;
    for (uint8_t r = 0; r < n; ++r) {
      if (raw[r] == 0) {
        wire[code] = static_cast<uint8_t>(w - code);
        code = w++;
      } else {
        wire[w++] = raw[r];
      }
    }
    wire[code] = static_cast<uint8_t>(w - code);
    wire[w++] = 0;
    FrameDecoder dec;
    for (uint8_t i = 0; i < w; ++i) CHECK_FALSE(dec.push(wire[i], bits(address)));
    CHECK(dec.counters().malformed == 1);
  }
}

TEST_CASE("an end's address: set and kept across a key change, written into every frame, address 0 the lone rover's bytes") {
  const uint8_t key[16] = {9, 8, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6};
  FrameAuth auth;
  CHECK(auth.version_byte() == kProtocolVersion);   // a new end: a lone rover, unsigned
  auth.set_address(3);
  CHECK(auth.address_bits() == 0x60);
  auth.begin(key);
  CHECK(auth.keyed());
  CHECK(auth.version_byte() == (kProtocolVersion | 0x60 | kSignFlag));
  auth.begin(nullptr);
  CHECK_FALSE(auth.keyed());
  CHECK(auth.version_byte() == (kProtocolVersion | 0x60));
  auth.set_address(0);
  CHECK(auth.version_byte() == kProtocolVersion);
  // Address 0 frames exactly as encode_frame without an end (the golden frames' bytes).
  const uint8_t payload[2] = {7, 33};
  uint8_t with_end[kMaxEncodedFrame], without[kMaxEncodedFrame];
  const uint8_t a = encode_frame(msg::Ack::kId, 4, payload, 2, with_end, &auth);
  const uint8_t b = encode_frame(msg::Ack::kId, 4, payload, 2, without);
  REQUIRE(a == b);
  CHECK(memcmp(with_end, without, a) == 0);
}
