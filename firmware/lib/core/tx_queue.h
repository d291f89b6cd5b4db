// Frames waiting to leave over the link. A frame goes in whole or not at all (and is counted as
// dropped), so the host never sees half a frame from us.
//
// Frames are queued raw (length, id, seq, payload) and framed (CRC, COBS; signed with a key)
// only when they are about to leave, by take(). Signing costs the Uno 0.3-0.8 ms a frame: a
// keyed rover signs at most one a step, and none in a step that has done a heavy job (a FIX, a
// sonar result, a planner slice), so what a step says does not add to its worst case (a FIX
// step that also reaches a waypoint sends its EVENT a step later). Without a key every frame is
// framed at once.
//
// A rover of a fleet ([fleet]) takes whole frames only (another rover's bytes may follow its own
// on the air: never half a frame), within what its grant leaves; it frames what it can between
// grants, so that a grant's bytes are ready when it opens.
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

  /// Queues a message: its bytes are its payload (wire_layout.h).
  template <typename Msg>
  void send(const Msg& m) {
    send_payload(Msg::kId, reinterpret_cast<const uint8_t*>(&m), Msg::kPayloadSize);
  }
  /// Queues a payload as a raw frame (one copy of this code for every message type).
  void send_payload(uint8_t msg_id, const uint8_t* payload, uint8_t len);
  /// Frames what is due, signed with auth's key when it has one (then one frame at most, none if
  /// !may_frame), then takes up to max framed bytes: n of them at the pointer returned, valid
  /// until the next send_payload() or take() (the shell writes them to the serial port right
  /// after the step). whole (a fleet's rover): only whole frames, and it frames whatever the
  /// queue has room for, whatever max is (0 between grants).
  const uint8_t* take(FrameAuth& auth, uint8_t max, bool may_frame, uint8_t& n, bool whole = false);
  uint16_t dropped() const { return dropped_; }
  /// A keyed queue whose framed bytes have all gone and whose next frame waits to be signed: a
  /// step that can do without its heavy job (a planner slice) leaves the time to take() for it.
  bool wants_signing(const FrameAuth& auth) const { return ready_ == 0 && count_ > taken_ && auth.keyed(); }
  /// Bytes queued, framed or not.
  uint8_t size() const { return static_cast<uint8_t>(count_ - taken_); }

 private:
  void drop_taken();
  bool frame_next(FrameAuth& auth);

  // buf_[0, ready_) framed bytes, then raw frames to count_: (len, id, seq, payload[len]).
  uint8_t buf_[kCapacity] = {};
  uint8_t count_ = 0;
  uint8_t ready_ = 0;
  uint8_t taken_ = 0;             // bytes at the front given out by the last take(), dropped before the next change
  uint8_t seq_ = 0;
  uint16_t dropped_ = 0;
};

}  // namespace core
}  // namespace rovernav
