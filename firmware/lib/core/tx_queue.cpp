#include "tx_queue.h"

namespace rovernav {
namespace core {

void TxQueue::send_payload(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
  uint8_t frame[kMaxEncodedFrame];
  const uint8_t n = encode_frame(msg_id, seq_, payload, len, frame);
  if (!push(frame, n)) {
    ++dropped_;
    return;
  }
  ++seq_;
}

bool TxQueue::push(const uint8_t* data, uint8_t n) {
  if (n == 0 || n > kCapacity - count_) return false;
  uint16_t tail = static_cast<uint16_t>(head_ + count_) % kCapacity;
  for (uint8_t i = 0; i < n; ++i) {
    buf_[tail] = data[i];
    tail = static_cast<uint16_t>((tail + 1) % kCapacity);
  }
  count_ = static_cast<uint8_t>(count_ + n);
  return true;
}

uint8_t TxQueue::take(uint8_t* out, uint8_t max) {
  uint8_t n = 0;
  while (n < max && count_ > 0) {
    out[n++] = buf_[head_];
    head_ = static_cast<uint8_t>((head_ + 1) % kCapacity);
    --count_;
  }
  return n;
}

}  // namespace core
}  // namespace rovernav
