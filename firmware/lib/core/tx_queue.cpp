#include "tx_queue.h"

#include "noinline.h"

namespace rovernav {
namespace core {

namespace {
enum : uint8_t {
  kRawHead = 3,   // length, id, seq
  // What framing adds to a raw frame at most (a signature, the CRC, COBS's code byte and the
  // delimiter, less the raw head). A frame is queued only if this much room is left behind it: a
  // queue filled with raw frames to the last byte could frame none of them, and would never
  // say anything again.
  kFramingGrowth = kFrameHeader + kFrameCrc + kFrameSignature + 2 - kRawHead,
};
}  // namespace

ROVERNAV_NOINLINE void TxQueue::send_payload(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
  drop_taken();
  if (len > kMaxPayload || kRawHead + kFramingGrowth + len > kCapacity - count_) {
    ++dropped_;
    return;
  }
  uint8_t* at = buf_ + count_;
  at[0] = len;
  at[1] = msg_id;
  at[2] = seq_++;
  for (uint8_t i = 0; i < len; ++i) at[kRawHead + i] = payload[i];
  count_ = static_cast<uint8_t>(count_ + kRawHead + len);
}

void TxQueue::drop_taken() {
  if (taken_ == 0) return;
  count_ = static_cast<uint8_t>(count_ - taken_);
  ready_ = static_cast<uint8_t>(ready_ - taken_);
  for (uint8_t i = 0; i < count_; ++i) buf_[i] = buf_[taken_ + i];   // at most 128 bytes, 30 us on the Uno
  taken_ = 0;
}

// Frames the first raw frame in place (it grows by the signature, the CRC, COBS's code byte
// and the delimiter: the raw frames behind it move up). False if there is none, or no room.
ROVERNAV_NOINLINE bool TxQueue::frame_next(FrameAuth& auth) {
  if (ready_ == count_) return false;
  uint8_t* raw = buf_ + ready_;
  const uint8_t len = raw[0];
  const bool sign = auth.keyed();
  const uint8_t framed = static_cast<uint8_t>(len + kFrameHeader + kFrameCrc + (sign ? kFrameSignature : 0) + 2);
  const uint8_t grow = static_cast<uint8_t>(framed - (kRawHead + len));
  if (grow > kCapacity - count_) return false;
  for (uint8_t i = static_cast<uint8_t>(count_ - ready_ - kRawHead - len); i > 0; --i) {
    raw[framed + i - 1] = raw[kRawHead + len + i - 1];   // the raw frames behind, moved up
  }
  // (len, id, seq, payload) to (COBS code, version, id, seq, payload): id to the payload's end
  // move up a byte, into the room just made, and are framed where they lie (no copy of them).
  for (uint8_t i = static_cast<uint8_t>(kRawHead - 1 + len); i > 0; --i) raw[i + 1] = raw[i];
  frame_in_place(raw, static_cast<uint8_t>(kFrameHeader + len), &auth);
  ready_ = static_cast<uint8_t>(ready_ + framed);
  count_ = static_cast<uint8_t>(count_ + grow);
  return true;
}

const uint8_t* TxQueue::take(FrameAuth& auth, uint8_t max, bool may_frame, uint8_t& n, bool whole) {
  drop_taken();
  const uint8_t frame_to = whole ? static_cast<uint8_t>(kCapacity) : max;
  if (auth.keyed()) {
    if (may_frame && ready_ < frame_to) frame_next(auth);
  } else {
    while (ready_ < frame_to && frame_next(auth)) {   // a CRC, 1.3 us a byte: all that fit go at once
    }
  }
  uint8_t k = ready_ < max ? ready_ : max;
  if (whole) {
    while (k > 0 && buf_[k - 1] != 0x00) --k;   // back to the last frame's delimiter (COBS: its only 0x00)
  }
  n = taken_ = k;
  return buf_;
}

}  // namespace core
}  // namespace rovernav
