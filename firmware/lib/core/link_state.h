// The link's state: frames out, the host's HELLO and HEARTBEAT, a path arriving in chunks, and
// the signatures' key and counters.
#pragma once
#include <stdint.h>

#include "frame_auth.h"
#include "messages_gen.h"
#include "mission_state.h"
#include "tx_queue.h"

namespace rovernav {
namespace core {

/// Written by link_in.cpp and link_out.cpp. rover.cpp's begin() and step() through the functions
/// below (begin, first_step, set_fleet, grant_room, status_sent, watch_counters; take_persist and take_key_change for
/// Rover::persist_due() and Rover::take_key_change()) and the queue's and the key's own interfaces
/// (tx.take, auth.begin, auth.resume). (The store's bookkeeping is here, inline, not moved to
/// link_out.cpp: out of rover.cpp's unit, the same code cost the 7.3 image 8 bytes, its functions
/// placed otherwise and fewer calls relaxed to RCALL.) detour.cpp borrows `stage` as the planner's scratch while no path is arriving (staging false).
struct LinkState {
  TxQueue tx;
  uint32_t boot_id = 0;
  uint16_t reset_cause = 0;
  uint8_t camera = 0;                    ///< CameraState from HEARTBEAT
  uint16_t last_status_ms = 0;           ///< modulo 65,536: STATUS goes every status_period_ms (<= 10 s)
  // a path arriving in chunks (else the detour planner's scratch)
  Waypoint stage[kMaxWaypoints] = {};
  uint8_t stage_total = 0;
  uint8_t stage_count = 0;
  uint16_t stage_id = 0;
  bool staging = false;
  uint8_t last_chunk = 0;                ///< first_index + 1 of the last chunk taken (0: none)
  // signatures: the key, the counters, what the shell must store
  FrameAuth auth;
  uint32_t boot_ms = 0;                  ///< the first step's time: PROVISION's window runs from it
  uint8_t stored_tx_b2 = 0;              ///< byte 2 of the tx counter last handed to the shell to store
  uint8_t stored_rx_hi[4] = {};          ///< bytes 2-5 of the rx counter last handed to the shell
  uint16_t auth_reported = 0;            ///< refusals counted when LINK_AUTH last went out
  uint8_t grant_left = 0;                ///< a fleet rover's bytes left in its grant ([fleet]); 0: none
  bool schema_ok : 1;                    ///< the host's HELLO carried our schema hash
  bool persist_due : 1;                  ///< the counters are to be stored (Rover::persist_due())
  bool persisted_once : 1;               ///< ... and have been since boot
  bool fix_verified : 1;                 ///< the decoder holds a FIX whose tag passed: next step's job
  uint8_t key_change : 2;                ///< a PROVISION for the shell to store: kKeyStore / kKeyErase
  bool fleet : 1;                        ///< a rover of a fleet (fleet_id 1..4): it speaks only in a grant

  void begin(uint32_t boot, uint16_t cause) {
    boot_id = boot;
    reset_cause = cause;
  }
  /// The first step: PROVISION's window and STATUS's period start, and a fleet rover's first grant
  /// opens (its boot HELLO and EVENT go out unasked: the host learns it reset, and `rovernav
  /// provision` that it has just booted).
  void first_step(uint32_t now_ms) {
    boot_ms = now_ms;
    status_sent(now_ms);
    grant_opens();
  }
  /// A frame from the host taken (or the first step): a fleet rover's grant opens ([fleet]).
  void grant_opens() { grant_left = kGrantBytes; }
  /// fleet_id 0: a lone rover (address 0, talks freely); k = 1..kMaxRovers: rover k of a fleet,
  /// address k - 1, speaking only in its grants. The caller has checked fleet_id <= kMaxRovers.
  void set_fleet(uint8_t fleet_id) {
    fleet = fleet_id != 0;
    auth.set_address(fleet ? static_cast<uint8_t>(fleet_id - 1) : 0);
  }
  uint8_t fleet_id() const { return fleet ? static_cast<uint8_t>((auth.address_bits() >> kAddressShift) + 1) : 0; }
  /// The bytes a fleet rover may hand its UART this step, of `room`, `since_ms` after the step that
  /// opened its grant: none past kGrantMs (the grant closes for good), none past kGrantBytes.
  uint8_t grant_room(uint8_t room, uint16_t since_ms) {
    if (since_ms > kGrantMs) grant_left = 0;
    return room < grant_left ? room : grant_left;
  }
  void status_sent(uint32_t now_ms) { last_status_ms = static_cast<uint16_t>(now_ms); }

  // What the shell stores (Rover::persist_due(), Rover::take_key_change(); each step: watch_counters()).
  /// With a key, notes when the counters are due to be stored: at the first step (the counters
  /// resumed past the stored ones must be stored at once: a second reset would resume from the
  /// same place), and when one has passed a multiple of 65,536 since it was stored: the rover's
  /// own counts its frames (byte 2 changes), the host's is its clock and may jump (any of bytes 2-5).
  void watch_counters() {
    if (!auth.keyed()) return;
    bool moved = !persisted_once || auth.tx_last().b[2] != stored_tx_b2;
    for (uint8_t i = 0; i < 4; ++i) moved = moved || auth.rx_last().b[2 + i] != stored_rx_hi[i];
    if (moved) persisted_once = persist_due = true;
  }
  static_assert(kSignPersistStep == 65536UL, "watch_counters() compares the counters from byte 2 up");
  /// The counters to store now, once per change (see watch_counters()).
  bool take_persist(Counter48& tx_counter, Counter48& rx_counter) {
    if (!persist_due) return false;
    persist_due = false;
    tx_counter = auth.tx_last();
    rx_counter = auth.rx_last();
    stored_tx_b2 = tx_counter.b[2];
    for (uint8_t i = 0; i < 4; ++i) stored_rx_hi[i] = rx_counter.b[2 + i];
    return true;
  }
  /// A PROVISION taken (kKeyStore, kKeyErase), once; 0 if none.
  uint8_t take_key_change() {
    const uint8_t change = key_change;
    key_change = 0;
    return change;
  }
};

}  // namespace core
}  // namespace rovernav
