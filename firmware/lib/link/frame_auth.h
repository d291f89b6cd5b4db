// The link's signatures ([signing] in protocol/messages.toml): one end's key, the counter of
// the frames it signs and the last counter it accepted from the other end; and its address
// ([fleet]), which with the key makes the version byte its frames carry.
//
// Receiving (check): a rover with no key takes unsigned frames and refuses signed ones
// (unverified); with a key it refuses unsigned commands but the few listed in [signing].unsigned
// (not_signed), frames whose counter is not above the last accepted (replayed: checked first, so
// a replay costs no tag), and frames whose tag is wrong (bad_tag). Only a good tag moves the
// counter on.
//
// Sending (sign): the counter counts the frames signed, from where it resumed after the last
// reset: the value stored then (EEPROM) plus kSignResetMargin. The shell stores both counters
// whenever one passes a multiple of kSignPersistStep (Rover::persist_due), so neither repeats
// across resets.
//
// A 48-bit counter is kept as its 6 bytes, little-endian as on the wire (a uint64_t costs the
// Uno about 1 KB of flash in library calls and inline code); it runs out after 8,900 years of
// milliseconds.
#pragma once
#include <stdint.h>

#include "frame.h"
#include "siphash.h"

namespace rovernav {

struct Counter48 {
  uint8_t b[kSignCounterBytes];
};
static_assert(sizeof(Counter48) == kSignCounterBytes && alignof(Counter48) == 1, "a Counter48 is its bytes");
/// c += ms (modulo 2^48), in place: a Counter48 returned by value costs the Uno a stack frame
/// and a copy at every call.
void counter_add(Counter48& c, uint32_t ms);
/// a + ms (modulo 2^48).
inline Counter48 counter_plus(const Counter48& a, uint32_t ms) {
  Counter48 r = a;
  counter_add(r, ms);
  return r;
}
/// Whether a > b.
bool counter_above(const Counter48& a, const Counter48& b);
/// The counter in 6 bytes (as on the wire, or as stored).
inline const Counter48& counter_at(const uint8_t* p) { return *reinterpret_cast<const Counter48*>(p); }

struct AuthCounters {
  uint16_t bad_tag;
  uint16_t replayed;
  uint16_t not_signed;
  uint16_t unverified;
};

/// What check() made of a frame.
enum class AuthResult : uint8_t { Accepted, Refused, RefusedAfterTag, AcceptedAfterTag };

class FrameAuth {
 public:
  /// key: 16 bytes, or nullptr for none. The rover's end: it checks kSignHostToRover frames and
  /// signs kSignRoverToHost ones.
  /// The address it keeps (set_address).
  void begin(const uint8_t* key);
  bool keyed() const { return (head_ & kSignFlag) != 0; }
  /// This end's address in a fleet ([fleet]: 0..kMaxRovers - 1; a lone rover's is 0), as it lies
  /// in the version byte (address_bits(): what FrameDecoder::push() takes).
  void set_address(uint8_t address) {
    head_ = static_cast<uint8_t>((head_ & kSignFlag) | ((address << kAddressShift) & kAddressMask));
  }
  uint8_t address_bits() const { return static_cast<uint8_t>(head_ & kAddressMask); }
  /// The version byte of the frames this end sends: the version, its address, kSignFlag with a key.
  uint8_t version_byte() const { return static_cast<uint8_t>(kProtocolVersion | head_); }
  const uint8_t* key() const { return key_; }

  /// Counters resumed after a reset: each the stored one plus kSignResetMargin. Call after begin().
  void resume(const Counter48& tx_persisted, const Counter48& rx_persisted);

  /// Checks a decoded frame. AcceptedAfterTag / RefusedAfterTag: a tag was computed (the
  /// step's heavy job).
  AuthResult check(const Frame& f);
  /// Appends the counter and the tag to the n bytes of raw (version .. payload); returns the
  /// new length. raw must have room for kFrameSignature more bytes.
  uint8_t sign(uint8_t* raw, uint8_t n);

  const Counter48& rx_last() const { return rx_last_; }
  const Counter48& tx_last() const { return tx_last_; }
  const AuthCounters& counters() const { return counters_; }

 private:
  void tag_of(uint8_t direction, const uint8_t* data, uint8_t len, uint8_t* tag) const;

  uint8_t key_[kSipKeyBytes] = {};
  uint8_t head_ = 0;   ///< kSignFlag (a key) | the address's bits: all of the version byte but the version
  static_assert((kSignFlag & kAddressMask) == 0 && ((kSignFlag | kAddressMask) & kVersionMask) == 0,
                "the flag, the address and the version have their own bits");
  Counter48 tx_last_ = {};
  Counter48 rx_last_ = {};
  AuthCounters counters_ = {};
};

}  // namespace rovernav
