// Frames on the wire (the one description is protocol/README.md):
//
//   frame = COBS(body) 0x00
//   body  = version:u8 | msg_id:u8 | seq:u8 | payload (0..kMaxPayload) | crc:u16le
//   crc   = CRC-16/CCITT-FALSE over version..payload
//   signed: version|kSignFlag ... payload | counter:u48le | tag:6 | crc (frame_auth.h checks
//   the counter and the tag; the decoder only finds them)
//   a fleet: bits kAddressShift.. of the version byte are the rover's address ([fleet]; 0 alone)
//
// FrameDecoder takes one byte at a time, decodes COBS as it goes into a single buffer,
// allocates nothing, resynchronises at the next 0x00 after garbage, and counts what it
// drops, in this order of checks (the host's decoder counts identically):
//   overlong    more than kMaxEncodedBody bytes before a delimiter
//   malformed   broken COBS, shorter than header + CRC, wrong version, wrong payload length
//   bad_crc     CRC mismatch
//   unknown_id  well-formed, but no message has that id
// An empty frame (two delimiters in a row) is not counted, nor is a frame for another address (a
// fleet's other rovers'), dropped after the version's check and before anything reads its id.
#pragma once
#include <stdint.h>

#include "messages_gen.h"

namespace rovernav {

enum : uint8_t {
  kFrameHeader = 3,
  kFrameCrc = 2,
  kFrameSignature = kSignCounterBytes + kSignTagBytes,
  /// Longest COBS body of a valid frame (a signed one): one code byte per 254 data bytes.
  kMaxEncodedBody = kMaxSignedRawFrame + (kMaxSignedRawFrame + 253) / 254,
  /// Longest frame on the wire, delimiter included.
  kMaxEncodedFrame = kMaxEncodedBody + 1,
};
static_assert(static_cast<int>(kMaxRawFrame) == kFrameHeader + static_cast<int>(kMaxPayload) + kFrameCrc,
              "raw frame size");
static_assert(static_cast<int>(kMaxEncodedFrame) <= static_cast<int>(kUartBufferBytes), "a frame must fit the Uno's serial buffers");

struct Frame {
  uint8_t version;
  uint8_t msg_id;
  uint8_t seq;
  uint8_t payload_len;
  const uint8_t* payload;  ///< points into the decoder's buffer; valid until the next push()
  /// A signed frame: the bytes from version to the counter's end (what the tag covers) are
  /// payload - kFrameHeader .. + signed_len, the tag follows them. 0: not signed.
  uint8_t signed_len;
  const uint8_t* signed_part() const { return payload - kFrameHeader; }
  const uint8_t* counter() const { return payload + payload_len; }
  const uint8_t* tag() const { return payload + payload_len + kSignCounterBytes; }
};

struct FrameCounters {
  uint16_t frames_ok;
  uint16_t bad_crc;
  uint16_t overlong;
  uint16_t unknown_id;
  uint16_t malformed;
};

class FrameDecoder {
 public:

  /// Feeds one byte. Returns true when it completes a valid frame for `address_bits` (the
  /// receiver's address in the version byte's bits, kAddressMask: FrameAuth::address_bits()),
  /// then readable by frame().
  bool push(uint8_t byte, uint8_t address_bits = 0);

  const Frame& frame() const { return frame_; }
  const FrameCounters& counters() const { return counters_; }
  /// Forgets a partial frame (counters are kept).
  void reset();

 private:
  bool finish(uint8_t address_bits);
  /// Counts a dropped frame in counter; returns false (finish()'s result).
  bool drop(uint16_t& counter);

  // All zero when nothing has come (a global decoder needs no start-up code).
  uint8_t raw_[kMaxSignedRawFrame] = {};
  uint8_t raw_len_ = 0;
  uint8_t encoded_len_ = 0;      // COBS bytes seen in this frame
  uint8_t block_left_ = 0;       // data bytes still due in the current COBS block
  bool zero_after_block_ = false;  // the current block stands for data followed by a 0x00
  bool overlong_ = false;
  Frame frame_ = {};
  FrameCounters counters_ = {};
};

class FrameAuth;

/// Writes the frame for (msg_id, seq, payload) to out, which must hold kMaxEncodedFrame bytes;
/// with auth's address, signed (counter and tag) when auth holds a key. Returns the bytes
/// written, delimiter included, or 0 if payload_len > kMaxPayload.
uint8_t encode_frame(uint8_t msg_id, uint8_t seq, const uint8_t* payload, uint8_t payload_len,
                     uint8_t* out, FrameAuth* auth = nullptr);

/// Frames in place the body whose msg_id, seq and payload are at out + 2 (n bytes with the
/// version byte at out + 1, which this writes: auth's, FrameAuth::version_byte(), else the bare
/// version): signed when auth holds a key, then the CRC, then
/// COBS from out on. out must hold kMaxEncodedFrame bytes. Returns the bytes written, delimiter
/// included. (encode_frame's second half: the TX queue frames its raw frames where they lie.)
uint8_t frame_in_place(uint8_t* out, uint8_t n, FrameAuth* auth);

/// Encodes a generated message: encode_message(msg::Fix{...}, seq, out).
template <typename Msg>
uint8_t encode_message(const Msg& m, uint8_t seq, uint8_t* out) {
  static_assert(static_cast<int>(Msg::kPayloadSize) <= static_cast<int>(kMaxPayload), "message larger than a frame");
  uint8_t payload[Msg::kPayloadSize > 0 ? Msg::kPayloadSize : 1];
  m.encode(payload);
  return encode_frame(Msg::kId, seq, payload, Msg::kPayloadSize, out);
}

/// Decodes frame f as Msg if it is one; returns false otherwise.
template <typename Msg>
bool decode_message(const Frame& f, Msg& m) {
  if (f.msg_id != Msg::kId || f.payload_len != static_cast<uint8_t>(Msg::kPayloadSize)) return false;
  m.decode(f.payload);
  return true;
}

}  // namespace rovernav
