// PROVISION and the owner's consent (link_in.cpp, on_provision): a rover with no key takes a key
// unsigned soon after a reset (first use); a rover with a key changes or forgets it only when the
// PROVISION is signed with that key (at any time) or the consent pin was held to GND at the reset
// (kSignConsentResetBit in the reset cause), never because it was reset: power-on, external,
// brown-out and watchdog resets alike leave it refusing with NACK needs_consent.
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {

const uint8_t kOwnerKey[16] = {0x51, 0x07, 0x9A, 0x33, 0xC2, 0x18, 0xE4, 0x6D, 0x2B, 0x90, 0x41, 0xF5, 0x0C, 0xB7, 0x68, 0x1E};
const uint8_t kNewKey[16] = {240, 241, 242, 243, 244, 245, 246, 247, 248, 249, 250, 251, 252, 253, 254, 255};
const uint8_t kStrangerKey[16] = {1, 1, 2, 3, 5, 8, 13, 21, 34, 55, 89, 144, 233, 121, 98, 219};

// MCUSR's reset flags (PORF, EXTRF, BORF, WDRF), none (what the sketch sees behind optiboot), all.
const uint16_t kResetCauses[] = {0x01, 0x02, 0x04, 0x08, 0x00, 0x0F};

/// A rover that has booted with `reset_cause`, holding kOwnerKey when keyed.
struct Rig {
  Bench b;
  uint64_t host_counter = 5097600000ull;   // the host's clock, ms since [signing].epoch
  uint8_t seq = 100;
  Rig(bool keyed, uint16_t reset_cause) {
    core::LinkSecrets s{};
    s.has_key = keyed;
    memcpy(s.key, kOwnerKey, sizeof s.key);
    b.rover.begin(0xB007, reset_cause, &s);
    b.run_ms(50);   // boot: HELLO and the boot EVENT (signed frames leave one a step)
  }
  /// After a key change the rover takes host counters only past the last one plus the reset
  /// margin (its HELLO says so): the host jumps past it.
  void jump_past_key_change() { host_counter += kSignResetMargin; }
  /// PROVISION {key, erase}, unsigned; returns its seq.
  uint8_t provision_unsigned(const uint8_t* key, uint8_t erase = 0) {
    msg::Provision p{};
    memcpy(p.key, key, sizeof p.key);
    p.erase = erase;
    uint8_t wire[kMaxEncodedFrame];
    const uint8_t n = encode_message(p, seq, wire);
    b.queue(wire, n);
    b.run_ms(30);
    return seq++;
  }
  /// Any host message, signed under sign_key with the next host counter; returns its seq.
  template <typename Msg>
  uint8_t send_signed(const Msg& m, const uint8_t* sign_key) {
    uint8_t raw[kMaxSignedRawFrame];
    uint8_t len = 0;
    raw[len++] = static_cast<uint8_t>(kProtocolVersion | kSignFlag);
    raw[len++] = Msg::kId;
    raw[len++] = seq;
    m.encode(raw + len);
    len = static_cast<uint8_t>(len + Msg::kPayloadSize);
    ++host_counter;
    for (int i = 0; i < kSignCounterBytes; ++i) raw[len++] = static_cast<uint8_t>(host_counter >> (8 * i));
    SipHash24 h;
    h.begin(sign_key);
    h.update(kSignHostToRover);
    h.update(raw, len);
    uint8_t tag[kSipTagBytes];
    h.finish(tag);
    for (int i = 0; i < kSignTagBytes; ++i) raw[len++] = tag[i];
    const uint16_t crc = crc16_ccitt_false(raw, len);
    raw[len++] = static_cast<uint8_t>(crc);
    raw[len++] = static_cast<uint8_t>(crc >> 8);
    uint8_t wire[kMaxEncodedFrame];
    uint8_t code_pos = 0, w = 1;
    for (uint8_t r = 0; r < len; ++r) {
      if (raw[r] == 0) {
        wire[code_pos] = static_cast<uint8_t>(w - code_pos);
        code_pos = w++;
      } else {
        wire[w++] = raw[r];
      }
    }
    wire[code_pos] = static_cast<uint8_t>(w - code_pos);
    wire[w++] = 0;
    b.queue(wire, w);
    b.run_ms(30);
    return seq++;
  }
  uint8_t provision_signed(const uint8_t* key, const uint8_t* sign_key, uint8_t erase = 0) {
    msg::Provision p{};
    memcpy(p.key, key, sizeof p.key);
    p.erase = erase;
    return send_signed(p, sign_key);
  }
  uint8_t stop_signed(const uint8_t* sign_key) {
    msg::Stop s{};
    return send_signed(s, sign_key);
  }
  bool holds(const uint8_t* key) const { return b.rover.signing() && memcmp(b.rover.link_key(), key, 16) == 0; }
  bool refused_for_consent(uint8_t s) const {
    msg::Nack n;
    return b.nack_for(s, n) && n.msg_id == msg::Provision::kId &&
           n.reason == static_cast<uint8_t>(NackReason::NeedsConsent) && n.detail == kSignConsentPin;
  }
};

}  // namespace

TEST_CASE("a rover with no key takes an unsigned PROVISION soon after any reset (first use), and not later") {
  for (uint16_t cause : kResetCauses) {
    CAPTURE(cause);
    Rig r(false, cause);
    const uint8_t s = r.provision_unsigned(kNewKey);
    CHECK(r.b.ack_for(s));
    CHECK(r.b.rover.take_key_change() == core::Rover::kKeyStore);
    CHECK(r.holds(kNewKey));
    CHECK(r.b.events(EventKind::KeyStored) == 1);

    Rig late(false, cause);
    late.b.run_ms(kSignProvisionWindowMs + 1000);
    const uint8_t s2 = late.provision_unsigned(kNewKey);
    msg::Nack n;
    REQUIRE(late.b.nack_for(s2, n));
    CHECK(n.reason == static_cast<uint8_t>(NackReason::NotNow));
    CHECK(n.detail == 6);
    CHECK(late.b.rover.take_key_change() == 0);
    CHECK_FALSE(late.b.rover.signing());
  }
}

TEST_CASE("a keyed rover refuses an unsigned new key or erase after every reset cause: needs_consent, nothing changes") {
  for (uint16_t cause : kResetCauses) {
    CAPTURE(cause);
    Rig r(true, cause);
    msg::Event boot;
    REQUIRE(r.b.events(EventKind::Boot, &boot) == 1);
    CHECK(boot.arg == cause);
    const uint8_t store = r.provision_unsigned(kNewKey);        // inside the window: still no
    const uint8_t erase = r.provision_unsigned(kNewKey, 1);
    r.b.run_ms(kSignProvisionWindowMs + 1000);
    const uint8_t later = r.provision_unsigned(kNewKey);        // past it: the same answer
    CHECK(r.refused_for_consent(store));
    CHECK(r.refused_for_consent(erase));
    CHECK(r.refused_for_consent(later));
    CHECK_FALSE(r.b.ack_for(store));
    CHECK_FALSE(r.b.ack_for(erase));
    CHECK(r.b.rover.take_key_change() == 0);
    CHECK(r.holds(kOwnerKey));
    CHECK(r.b.events(EventKind::KeyStored) == 0);
    // ... and the key it holds still commands it
    const uint8_t stop = r.stop_signed(kOwnerKey);
    CHECK(r.b.ack_for(stop));
  }
}

TEST_CASE("a keyed rover takes a PROVISION signed with its key at any time, and the new key from then on") {
  for (uint16_t cause : kResetCauses) {
    CAPTURE(cause);
    Rig r(true, cause);
    r.b.run_ms(60000);   // a minute after the reset: long past the unsigned window
    const uint8_t s = r.provision_signed(kNewKey, kOwnerKey);
    CHECK(r.b.ack_for(s));
    CHECK(r.b.rover.take_key_change() == core::Rover::kKeyStore);
    CHECK(r.holds(kNewKey));
    msg::Event stored;
    REQUIRE(r.b.events(EventKind::KeyStored, &stored) == 1);
    CHECK(stored.arg == 1);
    // The old key no longer commands it; the new one does.
    r.jump_past_key_change();
    const auto bad_tags = r.b.rover.auth_counters().bad_tag;
    const uint8_t old_stop = r.stop_signed(kOwnerKey);
    CHECK_FALSE(r.b.ack_for(old_stop));
    CHECK(r.b.rover.auth_counters().bad_tag == bad_tags + 1);
    const uint8_t new_stop = r.stop_signed(kNewKey);
    CHECK(r.b.ack_for(new_stop));
  }
}

TEST_CASE("a keyed rover forgets its key for an erase signed with it, and talks unsigned again") {
  Rig r(true, 0x01);
  r.b.run_ms(20000);
  const uint8_t s = r.provision_signed(kNewKey, kOwnerKey, 1);
  CHECK(r.b.ack_for(s));
  CHECK(r.b.rover.take_key_change() == core::Rover::kKeyErase);
  CHECK_FALSE(r.b.rover.signing());
}

TEST_CASE("a PROVISION signed with another key, or replayed, is refused by its signature and changes nothing") {
  Rig r(true, 0x02);
  const uint8_t forged = r.provision_signed(kNewKey, kStrangerKey);
  CHECK_FALSE(r.b.ack_for(forged));
  msg::Nack n;
  CHECK_FALSE(r.b.nack_for(forged, n));          // refused before it is read: no answer at all
  CHECK(r.b.rover.auth_counters().bad_tag == 1);
  CHECK(r.holds(kOwnerKey));

  // The owner's signed PROVISION, then the same bytes again after the owner changed back.
  const uint8_t s = r.provision_signed(kNewKey, kOwnerKey);
  REQUIRE(r.b.ack_for(s));
  CHECK(r.b.rover.take_key_change() == core::Rover::kKeyStore);
  r.seq = s;
  r.host_counter -= 1;                            // the very frame again: its counter, its tag
  const auto replayed = r.b.rover.auth_counters().replayed;
  r.provision_signed(kNewKey, kOwnerKey);
  CHECK(r.b.rover.take_key_change() == 0);
  CHECK(r.b.rover.auth_counters().replayed == replayed + 1);   // its counter is spent
  CHECK(r.holds(kNewKey));
}

TEST_CASE("a keyed rover reset with the consent pin held takes an unsigned key or erase within the window only") {
  for (uint16_t cause : kResetCauses) {
    CAPTURE(cause);
    const uint16_t with_consent = static_cast<uint16_t>(cause | kSignConsentResetBit);
    Rig r(true, with_consent);
    msg::Event boot;
    REQUIRE(r.b.events(EventKind::Boot, &boot) == 1);
    CHECK(boot.arg == with_consent);              // the host can see the consent in the boot EVENT
    const uint8_t s = r.provision_unsigned(kNewKey);
    CHECK(r.b.ack_for(s));
    CHECK(r.b.rover.take_key_change() == core::Rover::kKeyStore);
    CHECK(r.holds(kNewKey));

    Rig erase(true, with_consent);
    const uint8_t e = erase.provision_unsigned(kNewKey, 1);
    CHECK(erase.b.ack_for(e));
    CHECK(erase.b.rover.take_key_change() == core::Rover::kKeyErase);
    CHECK_FALSE(erase.b.rover.signing());

    Rig late(true, with_consent);
    late.b.run_ms(kSignProvisionWindowMs + 1000);
    const uint8_t l = late.provision_unsigned(kNewKey);
    msg::Nack n;
    REQUIRE(late.b.nack_for(l, n));
    CHECK(n.reason == static_cast<uint8_t>(NackReason::NotNow));
    CHECK(late.b.rover.take_key_change() == 0);
    CHECK(late.holds(kOwnerKey));
  }
}

TEST_CASE("a PROVISION with a bad erase value is refused as a bad value, signed or with consent") {
  Rig signed_rig(true, 0x01);
  const uint8_t s = signed_rig.provision_signed(kNewKey, kOwnerKey, 2);
  msg::Nack n;
  REQUIRE(signed_rig.b.nack_for(s, n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::BadValue));
  CHECK(signed_rig.holds(kOwnerKey));
  Rig consent(true, static_cast<uint16_t>(0x01 | kSignConsentResetBit));
  const uint8_t c = consent.provision_unsigned(kNewKey, 2);
  REQUIRE(consent.b.nack_for(c, n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::BadValue));
  CHECK(consent.holds(kOwnerKey));
}
