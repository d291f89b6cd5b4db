// A fleet on one radio ([fleet] in protocol/messages.toml): the fleet id stored with the key
// (PROVISION, LinkSecrets), the rover's address in every frame's version byte, and a rover of a
// fleet speaking only when spoken to: its UART gets whole frames only, in a grant opened by the
// host's poll (a FIX or a HEARTBEAT to it, the last frame of the host's slot) or by its reset, at
// most kGrantBytes, only within kGrantMs of the step that opened it. A lone rover (fleet id 0) talks as it always has.
#include <doctest.h>
#include <string.h>

#include "crc16.h"
#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {

const uint8_t kKey[16] = {0x51, 0x07, 0x9A, 0x33, 0xC2, 0x18, 0xE4, 0x6D, 0x2B, 0x90, 0x41, 0xF5, 0x0C, 0xB7, 0x68, 0x1E};
const uint8_t kOtherKey[16] = {1, 1, 2, 3, 5, 8, 13, 21, 34, 55, 89, 144, 233, 121, 98, 219};

uint8_t bits(uint8_t address) { return static_cast<uint8_t>(address << kAddressShift); }

/// What one step handed the UART, and when.
struct Sent {
  uint32_t t_ms;
  uint8_t len;
  bool ends_whole;   ///< its last byte is a frame's delimiter
};

/// A rover booted with fleet id `fleet_id` (keyed or not), the host talking to its address.
struct Fleet {
  Bench b;
  Sent sent[4096];
  int n_sent = 0;
  FrameDecoder heard;     // the host's decoder at the rover's address: every chunk must end whole
  int frames_heard = 0;
  int statuses = 0;
  uint64_t host_counter = 5097600000ull;
  uint8_t seq = 50;

  Fleet(uint8_t fleet_id, bool keyed) {
    core::LinkSecrets s{};
    s.has_key = keyed;
    memcpy(s.key, kKey, sizeof s.key);
    s.fleet_id = fleet_id;
    b.rover.begin(0xB007, 1, &s);
    b.address = fleet_id == 0 ? 0 : static_cast<uint8_t>(fleet_id - 1);
  }
  uint8_t address() const { return b.address; }
  /// One step, recording what it sent and checking that it ended on a frame's end.
  void step() {
    const uint32_t t = b.now_ms;
    b.step();
    if (b.out.tx_len == 0) return;
    REQUIRE(n_sent < 4096);
    sent[n_sent++] = {t, b.out.tx_len, b.out.tx[b.out.tx_len - 1] == 0x00};
    for (uint8_t i = 0; i < b.out.tx_len; ++i) {
      if (heard.push(b.out.tx[i], bits(address()))) {
        ++frames_heard;
        statuses += heard.frame().msg_id == msg::Status::kId;
      }
    }
  }
  void run_ms(uint32_t ms) {
    const uint32_t end = b.now_ms + ms;
    while (static_cast<int32_t>(end - b.now_ms) > 0) step();
  }
  /// Bytes sent in steps at times [from, to).
  int bytes_between(uint32_t from, uint32_t to) const {
    int n = 0;
    for (int i = 0; i < n_sent; ++i) n += (sent[i].t_ms >= from && sent[i].t_ms < to) ? sent[i].len : 0;
    return n;
  }
  /// The first step at or after `from` that sent anything (0: none).
  uint32_t first_sent_after(uint32_t from) const {
    for (int i = 0; i < n_sent; ++i) {
      if (sent[i].t_ms >= from) return sent[i].t_ms;
    }
    return 0;
  }
  bool all_whole() const {
    for (int i = 0; i < n_sent; ++i) {
      if (!sent[i].ends_whole) return false;
    }
    return true;
  }
  /// A message signed with `key` at the host's next counter, to `to` (an address): its bytes queued.
  template <typename Msg>
  void send_signed(const Msg& m, const uint8_t* key, uint8_t to) {
    uint8_t raw[kMaxSignedRawFrame];
    uint8_t len = 0;
    raw[len++] = static_cast<uint8_t>(kProtocolVersion | kSignFlag | bits(to));
    raw[len++] = Msg::kId;
    raw[len++] = seq++;
    m.encode(raw + len);
    len = static_cast<uint8_t>(len + Msg::kPayloadSize);
    ++host_counter;
    for (int i = 0; i < kSignCounterBytes; ++i) raw[len++] = static_cast<uint8_t>(host_counter >> (8 * i));
    SipHash24 h;
    h.begin(key);
    h.update(kSignHostToRover);
    h.update(raw, len);
    uint8_t tag[kSipTagBytes];
    h.finish(tag);
    for (int i = 0; i < kSignTagBytes; ++i) raw[len++] = tag[i];
    const uint16_t crc = crc16_ccitt_false(raw, len);
    raw[len++] = static_cast<uint8_t>(crc);
    raw[len++] = static_cast<uint8_t>(crc >> 8);
    uint8_t wire[kMaxEncodedFrame];
    uint8_t code = 0, w = 1;
    for (uint8_t r = 0; r < len; ++r) {
      if (raw[r] == 0) {
        wire[code] = static_cast<uint8_t>(w - code);
        code = w++;
      } else {
        wire[w++] = raw[r];
      }
    }
    wire[code] = static_cast<uint8_t>(w - code);
    wire[w++] = 0;
    b.queue(wire, w);
  }
  /// An unsigned HEARTBEAT to address `to` (the Bench's send() frames at b.address).
  void heartbeat_to(uint8_t to) {
    const uint8_t mine = b.address;
    b.address = to;
    msg::Heartbeat h{};
    b.send(h);
    b.address = mine;
  }
};

}  // namespace

TEST_CASE("a lone rover (fleet id 0) talks unasked, as it always has: STATUS every 0.2 s with nobody talking to it") {
  for (int keyed = 0; keyed < 2; ++keyed) {
    CAPTURE(keyed);
    Fleet f(0, keyed != 0);
    CHECK(f.b.rover.fleet_id() == 0);
    f.run_ms(2000);
    CHECK(f.statuses >= 9);
    CHECK(f.heard.counters().frames_ok == static_cast<uint16_t>(f.frames_heard));
  }
}

TEST_CASE("a rover of a fleet says its boot HELLO and EVENT in the grant its reset opens, then nothing until spoken to") {
  for (uint8_t fleet_id = 1; fleet_id <= kMaxRovers; ++fleet_id) {
    for (int keyed = 0; keyed < 2; ++keyed) {
      CAPTURE(fleet_id);
      CAPTURE(keyed);
      Fleet f(fleet_id, keyed != 0);
      CHECK(f.b.rover.fleet_id() == fleet_id);
      const uint32_t boot = f.b.now_ms;
      f.run_ms(3000);   // STATUS is due 15 times meanwhile, and queued: none may leave
      CHECK(f.bytes_between(boot, boot + kGrantMs + 1) > 0);
      CHECK(f.bytes_between(boot, boot + kGrantMs + 1) <= kGrantBytes);
      CHECK(f.bytes_between(boot + kGrantMs + 1, f.b.now_ms) == 0);
      CHECK(f.all_whole());
      CHECK(f.b.count<msg::Hello>() == 1);
      CHECK(f.b.events(EventKind::Boot) == 1);
      CHECK(f.statuses == 0);
      CHECK(f.b.rover.tx_dropped() > 0);   // what it would have said fills its queue
    }
  }
}

TEST_CASE("a host frame to a fleet rover's address opens a grant: whole frames, at most grant_bytes, only within grant_ms") {
  for (int keyed = 0; keyed < 2; ++keyed) {
    CAPTURE(keyed);
    Fleet f(3, keyed != 0);   // address 2
    f.run_ms(1000);           // its queue full of STATUS frames
    const int before = f.n_sent;
    for (int grant = 0; grant < 4; ++grant) {
      CAPTURE(grant);
      if (keyed) {
        f.send_signed(msg::Heartbeat{}, kKey, f.address());
      } else {
        f.heartbeat_to(f.address());
      }
      const uint32_t asked = f.b.now_ms;   // the frame reaches the rover in this step
      f.run_ms(500);
      const uint32_t opened = f.first_sent_after(asked);
      REQUIRE(opened == asked);            // the step that took the frame speaks at once (frames were ready)
      const int said = f.bytes_between(asked, asked + 500);
      CHECK(said > 0);
      CHECK(said <= kGrantBytes);
      CHECK(f.bytes_between(opened + kGrantMs + 1, asked + 500) == 0);
    }
    CHECK(f.n_sent > before);
    CHECK(f.all_whole());
    CHECK(f.statuses >= 4);
    CHECK(f.heard.counters().frames_ok == static_cast<uint16_t>(f.frames_heard));
  }
}

TEST_CASE("a frame that does not fit what the grant leaves waits whole for the next grant") {
  Fleet f(2, false);   // address 1, unsigned: a STATUS is 52 bytes on the wire, two do not fit a step's 64
  f.run_ms(1000);
  int per_grant[3] = {0, 0, 0};
  int statuses[3] = {0, 0, 0};
  for (int grant = 0; grant < 3; ++grant) {
    const int st = f.statuses;
    f.heartbeat_to(1);
    const uint32_t asked = f.b.now_ms;
    f.run_ms(300);
    per_grant[grant] = f.bytes_between(asked, asked + 300);
    statuses[grant] = f.statuses - st;
  }
  for (int grant = 0; grant < 3; ++grant) {
    CAPTURE(grant);
    CHECK(per_grant[grant] <= kGrantBytes);
    // One STATUS a step of the grant's two: a second in the same step would pass the UART's 64
    // bytes, and waits for the next step; a third would pass the grant's 128, and waits for the next grant.
    CHECK(statuses[grant] >= 1);
    CHECK(statuses[grant] <= 2);
  }
  CHECK(f.all_whole());
}

TEST_CASE("a frame for another address opens no grant and is not taken; a signed one is dropped before its tag") {
  for (int keyed = 0; keyed < 2; ++keyed) {
    CAPTURE(keyed);
    Fleet f(4, keyed != 0);   // address 3
    f.run_ms(500);
    const uint16_t taken = f.b.rover.rx_counters().frames_ok;
    const int sent = f.n_sent;
    for (uint8_t other = 0; other < 3; ++other) {
      if (keyed) {
        f.send_signed(msg::Heartbeat{}, kOtherKey, other);   // another rover's, under a key it does not hold
      } else {
        f.heartbeat_to(other);
      }
      f.run_ms(200);
    }
    CHECK(f.n_sent == sent);                                  // no grant: nothing said
    CHECK(f.b.rover.rx_counters().frames_ok == taken);        // none taken
    CHECK(f.b.rover.rx_counters().malformed == 0);            // nor counted as broken
    CHECK(f.b.rover.auth_counters().bad_tag == 0);            // no tag computed
    if (keyed) {
      f.send_signed(msg::Heartbeat{}, kOtherKey, f.address()); // its own address, the wrong key: checked, refused
      f.run_ms(200);
      CHECK(f.b.rover.auth_counters().bad_tag == 1);
      CHECK(f.n_sent == sent);                                // refused: no grant either
    }
  }
}

TEST_CASE("PROVISION stores the fleet id with the key: the ACK comes from the new address, and the rover waits to be spoken to") {
  for (uint8_t fleet_id = 0; fleet_id <= kMaxRovers; ++fleet_id) {
    CAPTURE(fleet_id);
    Fleet f(0, false);   // a lone rover with no key, just booted
    f.run_ms(50);
    msg::Provision p{};
    memcpy(p.key, kKey, sizeof p.key);
    p.fleet_id = fleet_id;
    f.b.send(p);   // to address 0, where the rover is
    const uint8_t s = f.b.last_host_seq();
    const uint8_t now_at = fleet_id == 0 ? 0 : static_cast<uint8_t>(fleet_id - 1);
    f.b.address = now_at;   // listen where the answer comes from
    f.run_ms(100);
    CHECK(f.b.ack_for(s));
    CHECK(f.b.rover.take_key_change() == core::Rover::kKeyStore);
    CHECK(f.b.rover.fleet_id() == fleet_id);
    CHECK(f.b.events(EventKind::KeyStored) == 1);
    const int statuses = f.statuses;
    f.run_ms(2000);
    if (fleet_id == 0) {
      CHECK(f.statuses > statuses);    // a lone rover talks on
    } else {
      CHECK(f.statuses == statuses);   // a fleet's waits for its grant
    }
  }
}

TEST_CASE("an erase stores the fleet id too; a fleet id past max_rovers is refused with NACK bad_value 3, nothing changed") {
  Fleet f(2, true);
  f.run_ms(50);
  msg::Provision bad{};
  memcpy(bad.key, kOtherKey, sizeof bad.key);
  bad.fleet_id = kMaxRovers + 1;
  f.send_signed(bad, kKey, f.address());
  const uint8_t bad_seq = static_cast<uint8_t>(f.seq - 1);
  for (int poll = 0; poll < 3; ++poll) {   // the host's polls: the NACK's grants (it may queue behind others)
    f.send_signed(msg::Heartbeat{}, kKey, f.address());
    f.run_ms(100);
  }
  msg::Nack n;
  REQUIRE(f.b.nack_for(bad_seq, n));
  CHECK(n.msg_id == msg::Provision::kId);
  CHECK(n.reason == static_cast<uint8_t>(NackReason::BadValue));
  CHECK(n.detail == 3);
  CHECK(f.b.rover.take_key_change() == 0);
  CHECK(f.b.rover.fleet_id() == 2);
  CHECK(memcmp(f.b.rover.link_key(), kKey, 16) == 0);

  msg::Provision erase{};
  erase.erase = 1;
  erase.fleet_id = 4;
  f.send_signed(erase, kKey, f.address());
  const uint8_t erase_seq = static_cast<uint8_t>(f.seq - 1);
  f.run_ms(50);
  f.b.address = 3;
  for (int poll = 0; poll < 3; ++poll) {   // the polls, at the new address, unsigned (the key is erased)
    f.heartbeat_to(3);
    f.run_ms(100);
  }
  CHECK(f.b.ack_for(erase_seq));
  CHECK(f.b.rover.take_key_change() == core::Rover::kKeyErase);
  CHECK_FALSE(f.b.rover.signing());
  CHECK(f.b.rover.fleet_id() == 4);
}

TEST_CASE("a grant closes grant_ms after the step that opened it, bytes left or not: what comes later waits") {
  for (int keyed = 0; keyed < 2; ++keyed) {
    CAPTURE(keyed);
    Fleet f(1, keyed != 0);   // address 0, a fleet's first rover
    f.run_ms(40);             // the boot grant over; STATUS not due before 0.2 s
    if (keyed) {
      f.send_signed(msg::Heartbeat{}, kKey, f.address());
    } else {
      f.heartbeat_to(f.address());
    }
    const uint32_t asked = f.b.now_ms;
    f.run_ms(20);
    CHECK(f.bytes_between(asked, f.b.now_ms) == 0);   // a grant with nothing to say: all its 96 bytes left
    f.b.gyro_alive = false;                            // the gyro's fault EVENT comes ~50 ms later, past the grant
    f.run_ms(150);
    CHECK(f.b.rover.fault() == FaultCode::GyroSilent);
    CHECK(f.b.events(EventKind::Fault) == 0);
    CHECK(f.bytes_between(asked, f.b.now_ms) == 0);
    // The next grant carries it.
    if (keyed) {
      f.send_signed(msg::Heartbeat{}, kKey, f.address());
    } else {
      f.heartbeat_to(f.address());
    }
    f.run_ms(30);
    CHECK(f.b.events(EventKind::Fault) == 1);
    CHECK(f.all_whole());
  }
}
