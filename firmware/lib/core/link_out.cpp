// Frames to the host, queued whole (TxQueue): ACK and NACK, HELLO, EVENT, STATUS, and the
// sonar's readings as OBSTACLE frames.
#include "rover.h"

#include <stddef.h>
#include <string.h>

#include "angles.h"
#include "float_ops.h"
#include "le_bytes.h"

namespace rovernav {
namespace core {

void Rover::ack(uint8_t msg_id, uint8_t seq) {
  msg::Ack a;
  a.msg_id = msg_id;
  a.seq = seq;
  tx_.send(a);
}

void Rover::nack(uint8_t msg_id, uint8_t seq, NackReason reason, uint16_t detail) {
  msg::Nack n;
  n.msg_id = msg_id;
  n.seq = seq;
  n.reason = static_cast<uint8_t>(reason);
  n.detail = detail;
  tx_.send(n);
}

void Rover::send_hello() {
  msg::Hello h{};
  h.schema_hash = kSchemaHash;
  h.boot_id = boot_id_;
  h.firmware_version = kFirmwareVersion;
  h.role = static_cast<uint8_t>(Role::Rover);
  h.max_waypoints = kMaxWaypoints;
  if (auth_.keyed()) {
    // The host's counter must pass ours: after a reset we take none below the stored one plus
    // the margin, so that a recording of the last session cannot be played back.
    Counter48 least = auth_.rx_last();
    counter_add(least, 1);
    h.signing = 1;
    h.min_counter_lo = le::get_u32(least.b);
    h.min_counter_hi = le::get_u16(least.b + 4);
  }
  tx_.send(h);
}

void Rover::send_event(EventKind kind, uint16_t arg) {
  msg::Event e;
  e.kind = static_cast<uint8_t>(kind);
  e.arg = arg;
  e.time_ms = last_ms_;
  const Point here = here_mm();
  e.x_mm = here.x_mm;
  e.y_mm = here.y_mm;
  tx_.send(e);
}

ROVERNAV_NOINLINE void Rover::send_status() {
  msg::Status s;
  s.time_ms = last_ms_;
  // The fix's age first, with last_ms_ just loaded: taken after the floats below, last_ms_ was held
  // across all their calls, in four more registers to save and restore.
  s.fix_age_ms = had_fix_ ? saturate_u16(static_cast<float>(last_ms_ - last_fix_ms_)) : 65535;
  s.state = static_cast<uint8_t>(state_);
  s.flags = flags();
  s.fault = static_cast<uint8_t>(fault_);
  s.path_id = path_id_;
  s.waypoint_index = wp_;
  const Point here = here_mm();
  s.x_mm = here.x_mm;
  s.y_mm = here.y_mm;
  s.heading_cdeg = rad_to_cdeg(est_.heading_rad());
  const float sd_x = sqrt_or_zero(est_.p(Estimator::kXX)), sd_y = sqrt_or_zero(est_.p(Estimator::kYY));
  s.sd_x_mm = saturate_u16(sd_x);
  s.sd_y_mm = saturate_u16(sd_y);
  const float denom = sd_x * sd_y;
  s.corr_xy_permille = positive(denom) ? saturate_i16(1000.0f * est_.p(Estimator::kXY) / denom) : 0;
  s.sd_heading_cdeg = saturate_u16(rad_to_deg(sqrt_or_zero(est_.p(Estimator::kTT))) * 100.0f);
  s.dr_distance_mm = saturate_u16(dr_distance_mm_);
  s.left_pwm = left_cmd_;
  s.right_pwm = right_cmd_;
  // The decoder's five counters are STATUS's five rx fields, in the same order and width.
  static_assert(sizeof(FrameCounters) == 10 && offsetof(msg::Status, rx_malformed) == offsetof(msg::Status, rx_ok) + 8,
                "FrameCounters lies as STATUS's rx_ok .. rx_malformed");
  memcpy(static_cast<void*>(&s.rx_ok), &decoder_.counters(), sizeof(FrameCounters));
  s.tx_dropped = tx_.dropped();
  tx_.send(s);
}

// LINK_AUTH in STATUS's place when the refusals have changed since it last went out.
bool Rover::send_link_auth() {
  const AuthCounters& c = auth_.counters();
  const uint16_t sum = static_cast<uint16_t>(c.bad_tag + c.replayed + c.not_signed + c.unverified);
  if (sum == auth_reported_) return false;
  auth_reported_ = sum;
  msg::LinkAuth a;
  a.signing = auth_.keyed() ? 1 : 0;
  static_assert(sizeof(AuthCounters) == 8 && offsetof(msg::LinkAuth, unverified) == offsetof(msg::LinkAuth, bad_tag) + 6,
                "AuthCounters lies as LINK_AUTH's bad_tag .. unverified");
  memcpy(static_cast<void*>(&a.bad_tag), &c, sizeof c);
  tx_.send(a);
  return true;
}

ROVERNAV_NOINLINE void Rover::send_reading(int16_t bearing_cdeg, uint16_t range_mm) {
  msg::Obstacle o;
  o.scan_id = scan_id_;
  o.bearing_cdeg = bearing_cdeg;
  o.range_mm = range_mm;
  const Point here = here_mm();
  o.x_mm = here.x_mm;
  o.y_mm = here.y_mm;
  o.heading_cdeg = rad_to_cdeg(est_.heading_rad());
  o.sd_mm = saturate_u16(est_.position_sd_mm());
  tx_.send(o);
}

ROVERNAV_NOINLINE void Rover::report_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  // Said kSayTimes times: the host plans with what it heard, and the rover takes its path on the
  // host's word only when it heard every echo of the sweep (HEARTBEAT's scan_heard). The host
  // drops the copies.
  for (uint8_t i = 0; i < kSayTimes; ++i) send_reading(bearing_cdeg, range_mm);
  ++scan_echoes_;
  remember_echo(bearing_cdeg, range_mm);
}

void Rover::report_clear(int16_t bearing_cdeg) { send_reading(bearing_cdeg, 0); }

}  // namespace core
}  // namespace rovernav
