// Bytes waiting to leave over the link, as whole frames: a frame goes in whole or not at all
// (and is counted as dropped), so the host never sees half a frame from us.
#pragma once
#include <stdint.h>

#include "frame.h"
#include "frame_auth.h"

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
  /// Frames from now on are signed with auth's key, when it has one.
  void sign_with(FrameAuth* auth) { auth_ = auth; }
  /// Takes up to max queued bytes: n of them at the pointer returned, valid until the next
  /// send_payload() or take() (the shell writes them to the serial port right after the step).
  const uint8_t* take(uint8_t max, uint8_t& n);
  uint16_t dropped() const { return dropped_; }
  uint8_t size() const { return static_cast<uint8_t>(count_ - taken_); }

 private:
  void drop_taken();

  uint8_t buf_[kCapacity] = {};   // the queue, from buf_[0]: no wrapping, so take() gives one piece
  uint8_t count_ = 0;
  uint8_t taken_ = 0;             // bytes at the front given out by the last take(), dropped before the next change
  uint8_t seq_ = 0;
  uint16_t dropped_ = 0;
  FrameAuth* auth_ = nullptr;
};

}  // namespace core
}  // namespace rovernav
