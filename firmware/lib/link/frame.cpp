#include "frame.h"

#include "crc16.h"
#include "frame_auth.h"

namespace rovernav {

void FrameDecoder::reset() {
  raw_len_ = 0;
  encoded_len_ = 0;
  block_left_ = 0;
  zero_after_block_ = false;
  overlong_ = false;
}

bool FrameDecoder::push(uint8_t byte, uint8_t address_bits) {
  if (byte == 0x00) {
    const bool ok = finish(address_bits);
    reset();
    return ok;
  }
  if (overlong_) return false;
  if (encoded_len_ >= kMaxEncodedBody) {
    overlong_ = true;
    return false;
  }
  ++encoded_len_;
  if (block_left_ == 0) {
    // A code byte: the previous block (if any) stood for its data plus a zero, unless it
    // was a full 254-byte block (code 0xFF).
    if (encoded_len_ > 1 && zero_after_block_) raw_[raw_len_++] = 0;
    block_left_ = static_cast<uint8_t>(byte - 1);
    zero_after_block_ = byte != 0xFF;
    return false;
  }
  raw_[raw_len_++] = byte;  // cannot overflow: raw_len_ < encoded_len_ <= kMaxEncodedBody
  --block_left_;
  return false;
}

// Out of line: the count written out at each of the six ways to drop a frame costs the Uno
// more flash than the calls.
__attribute__((noinline)) bool FrameDecoder::drop(uint16_t& counter) {
  ++counter;
  return false;
}

bool FrameDecoder::finish(uint8_t address_bits) {
  if (overlong_) return drop(counters_.overlong);
  if (encoded_len_ == 0) return false;  // two delimiters in a row
  if (block_left_ != 0 || raw_len_ < kFrameHeader + kFrameCrc) return drop(counters_.malformed);
  const uint8_t body_len = static_cast<uint8_t>(raw_len_ - kFrameCrc);
  const uint16_t crc = static_cast<uint16_t>(raw_[body_len] | (raw_[body_len + 1] << 8));
  if (crc16_ccitt_false(raw_, body_len) != crc) return drop(counters_.bad_crc);
  const uint8_t version = raw_[0];
  const bool is_signed = (version & kSignFlag) != 0;
  if ((version & kVersionMask) != kProtocolVersion || (is_signed && body_len < kFrameHeader + kFrameSignature)) {
    return drop(counters_.malformed);
  }
  // Another rover's (a fleet shares the radio): not ours to read, nor a fault of the link's.
  if ((version & kAddressMask) != address_bits) return false;
  const int16_t expected = payload_size(raw_[1]);
  if (expected < 0) return drop(counters_.unknown_id);
  const uint8_t payload_len = static_cast<uint8_t>(body_len - kFrameHeader - (is_signed ? kFrameSignature : 0));
  if (payload_len != expected) return drop(counters_.malformed);
  frame_.version = version;
  frame_.msg_id = raw_[1];
  frame_.seq = raw_[2];
  frame_.payload_len = payload_len;
  frame_.payload = raw_ + kFrameHeader;
  frame_.signed_len = is_signed ? static_cast<uint8_t>(kFrameHeader + payload_len + kSignCounterBytes) : 0;
  ++counters_.frames_ok;
  return true;
}

uint8_t encode_frame(uint8_t msg_id, uint8_t seq, const uint8_t* payload, uint8_t payload_len,
                     uint8_t* out, FrameAuth* auth) {
  if (payload_len > kMaxPayload) return 0;
  // Build the raw body in place after one spare byte, then COBS-encode forwards: the
  // encoder never writes past the byte it is about to read, so one buffer suffices.
  uint8_t* raw = out + 1;
  uint8_t n = 1;   // the version: frame_in_place writes it
  raw[n++] = msg_id;
  raw[n++] = seq;
  for (uint8_t i = 0; i < payload_len; ++i) raw[n++] = payload[i];
  return frame_in_place(out, n, auth);
}

uint8_t frame_in_place(uint8_t* out, uint8_t n, FrameAuth* auth) {
  uint8_t* raw = out + 1;
  raw[0] = auth != nullptr ? auth->version_byte() : static_cast<uint8_t>(kProtocolVersion);
  if (raw[0] & kSignFlag) n = auth->sign(raw, n);
  const uint16_t crc = crc16_ccitt_false(raw, n);
  raw[n++] = static_cast<uint8_t>(crc & 0xFFu);
  raw[n++] = static_cast<uint8_t>(crc >> 8);
  // Frames are shorter than 254 bytes, so every block is ended by a zero or by the end.
  uint8_t code_pos = 0;
  uint8_t w = 1;
  for (uint8_t r = 0; r < n; ++r) {
    const uint8_t b = raw[r];
    if (b == 0) {
      out[code_pos] = static_cast<uint8_t>(w - code_pos);
      code_pos = w++;
    } else {
      out[w++] = b;
    }
  }
  out[code_pos] = static_cast<uint8_t>(w - code_pos);
  out[w++] = 0x00;
  return w;
}

}  // namespace rovernav
