#include "frame_auth.h"

namespace rovernav {

void counter_add(Counter48& c, uint32_t ms) {
  uint16_t carry = 0;
  for (uint8_t i = 0; i < kSignCounterBytes; ++i) {
    carry = static_cast<uint16_t>(carry + c.b[i] + (ms & 0xFFu));
    c.b[i] = static_cast<uint8_t>(carry);
    carry >>= 8;
    ms >>= 8;
  }
}

bool counter_above(const Counter48& a, const Counter48& b) {
  for (uint8_t i = kSignCounterBytes; i > 0; --i) {
    if (a.b[i - 1] != b.b[i - 1]) return a.b[i - 1] > b.b[i - 1];
  }
  return false;
}

__attribute__((noinline)) void FrameAuth::begin(const uint8_t* key) {
  const bool keyed = key != nullptr;
  head_ = static_cast<uint8_t>((head_ & kAddressMask) | (keyed ? kSignFlag : 0));
  for (uint8_t i = 0; i < kSipKeyBytes; ++i) key_[i] = keyed ? key[i] : 0;
}

__attribute__((noinline)) void FrameAuth::resume(const Counter48& tx_persisted, const Counter48& rx_persisted) {
  tx_last_ = tx_persisted;
  counter_add(tx_last_, kSignResetMargin);
  rx_last_ = rx_persisted;
  counter_add(rx_last_, kSignResetMargin);
}

void FrameAuth::tag_of(uint8_t direction, const uint8_t* data, uint8_t len, uint8_t* tag) const {
  SipHash24 h;
  h.begin(key_);
  h.update(direction);
  h.update(data, len);
  h.finish(tag);
}

AuthResult FrameAuth::check(const Frame& f) {
  if (!keyed()) {
    if (f.signed_len == 0) return AuthResult::Accepted;
    ++counters_.unverified;
    return AuthResult::Refused;
  }
  if (f.signed_len == 0) {
    if (may_be_unsigned(f.msg_id)) return AuthResult::Accepted;
    ++counters_.not_signed;
    return AuthResult::Refused;
  }
  const Counter48& c = counter_at(f.counter());
  if (!counter_above(c, rx_last_)) {
    ++counters_.replayed;
    return AuthResult::Refused;
  }
  uint8_t tag[kSipTagBytes];
  tag_of(kSignHostToRover, f.signed_part(), f.signed_len, tag);
  uint8_t diff = 0;   // every byte compared, whatever the first difference
  for (uint8_t i = 0; i < kSignTagBytes; ++i) diff = static_cast<uint8_t>(diff | (tag[i] ^ f.tag()[i]));
  if (diff != 0) {
    ++counters_.bad_tag;
    return AuthResult::RefusedAfterTag;
  }
  rx_last_ = c;
  return AuthResult::AcceptedAfterTag;
}

uint8_t FrameAuth::sign(uint8_t* raw, uint8_t n) {
  counter_add(tx_last_, 1);
  for (uint8_t i = 0; i < kSignCounterBytes; ++i) raw[n++] = tx_last_.b[i];
  uint8_t tag[kSipTagBytes];
  tag_of(kSignRoverToHost, raw, n, tag);
  for (uint8_t i = 0; i < kSignTagBytes; ++i) raw[n++] = tag[i];
  return n;
}

}  // namespace rovernav
