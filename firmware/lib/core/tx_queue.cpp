#include "tx_queue.h"

namespace rovernav {
namespace core {

void TxQueue::send_payload(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
  // Encoded in place at the queue's end (no 64-byte frame on the stack): the frame's size is
  // known before, a COBS code byte and the delimiter on top of its raw bytes.
  drop_taken();
  const bool sign = auth_ != nullptr && auth_->keyed();
  const uint8_t need = static_cast<uint8_t>(len + kFrameHeader + kFrameCrc + (sign ? kFrameSignature : 0) + 2);
  if (len > kMaxPayload || need > kCapacity - count_) {
    ++dropped_;
    return;
  }
  count_ = static_cast<uint8_t>(count_ + encode_frame(msg_id, seq_, payload, len, buf_ + count_, auth_));
  ++seq_;
}

void TxQueue::drop_taken() {
  if (taken_ == 0) return;
  count_ = static_cast<uint8_t>(count_ - taken_);
  for (uint8_t i = 0; i < count_; ++i) buf_[i] = buf_[taken_ + i];   // at most 128 bytes, 30 us on the Uno
  taken_ = 0;
}

const uint8_t* TxQueue::take(uint8_t max, uint8_t& n) {
  drop_taken();
  n = count_ < max ? count_ : max;
  taken_ = n;
  return buf_;
}

}  // namespace core
}  // namespace rovernav
