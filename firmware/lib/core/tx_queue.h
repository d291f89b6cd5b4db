// Bytes waiting to leave over the link, as whole frames: a frame goes in whole or not at all
// (and is counted as dropped), so the host never sees half a frame from us.
#pragma once
#include <stdint.h>

#include "frame.h"

namespace rovernav {
namespace core {

class TxQueue {
 public:
  enum : uint8_t { kCapacity = 128 };
  static_assert(kCapacity >= 2 * kMaxEncodedFrame, "room for two frames at least");

  template <typename Msg>
  void send(const Msg& m) {
    uint8_t payload[Msg::kPayloadSize];
    m.encode(payload);
    send_payload(Msg::kId, payload, Msg::kPayloadSize);
  }
  /// Frames and queues a payload (one copy of this code for every message type).
  void send_payload(uint8_t msg_id, const uint8_t* payload, uint8_t len);
  /// Moves up to max queued bytes to out; returns how many.
  uint8_t take(uint8_t* out, uint8_t max);
  uint16_t dropped() const { return dropped_; }
  uint8_t size() const { return count_; }

 private:
  bool push(const uint8_t* data, uint8_t n);

  uint8_t buf_[kCapacity] = {};
  uint8_t head_ = 0;   // next byte to take
  uint8_t count_ = 0;
  uint8_t seq_ = 0;
  uint16_t dropped_ = 0;
};

}  // namespace core
}  // namespace rovernav
