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
  link_.tx.send(a);
}

void Rover::nack(uint8_t msg_id, uint8_t seq, NackReason reason, uint16_t detail) {
  msg::Nack n;
  n.msg_id = msg_id;
  n.seq = seq;
  n.reason = static_cast<uint8_t>(reason);
  n.detail = detail;
  link_.tx.send(n);
}

void Rover::send_hello() {
  msg::Hello h{};
  h.schema_hash = kSchemaHash;
  h.boot_id = link_.boot_id;
  h.firmware_version = kFirmwareVersion;
  h.role = static_cast<uint8_t>(Role::Rover);
  h.max_waypoints = kMaxWaypoints;
  if (link_.auth.keyed()) {
    // The host's counter must pass ours: after a reset we take none below the stored one plus
    // the margin, so that a recording of the last session cannot be played back.
    Counter48 least = link_.auth.rx_last();
    counter_add(least, 1);
    h.signing = 1;
    h.min_counter_lo = le::get_u32(least.b);
    h.min_counter_hi = le::get_u16(least.b + 4);
  }
  link_.tx.send(h);
}

void Rover::send_event(EventKind kind, uint16_t arg) {
  msg::Event e;
  e.kind = static_cast<uint8_t>(kind);
  e.arg = arg;
  e.time_ms = step_.now_ms();
  const Point here = here_mm();
  e.x_mm = here.x_mm;
  e.y_mm = here.y_mm;
  link_.tx.send(e);
}

ROVERNAV_NOINLINE void Rover::send_status() {
  msg::Status s;
  const uint32_t now = step_.now_ms();
  s.time_ms = now;
  // The fix's age first, with the step's time just loaded: taken after the floats below, it was held
  // across all their calls, in four more registers to save and restore.
  s.fix_age_ms = failsafe_.had_fix ? saturate_u16(static_cast<float>(now - failsafe_.last_fix_ms)) : 65535;
  s.state = static_cast<uint8_t>(step_.state);
  s.flags = flags();
  s.fault = static_cast<uint8_t>(failsafe_.fault);
  s.path_id = mission_.path_id;
  s.waypoint_index = mission_.wp;
  const Point here = here_mm();
  s.x_mm = here.x_mm;
  s.y_mm = here.y_mm;
  s.heading_cdeg = rad_to_cdeg(odometry_.est.heading_rad());
  const float sd_x = sqrt_or_zero(odometry_.est.p(Estimator::kXX)), sd_y = sqrt_or_zero(odometry_.est.p(Estimator::kYY));
  s.sd_x_mm = saturate_u16(sd_x);
  s.sd_y_mm = saturate_u16(sd_y);
  const float denom = sd_x * sd_y;
  s.corr_xy_permille = positive(denom) ? saturate_i16(1000.0f * odometry_.est.p(Estimator::kXY) / denom) : 0;
  s.sd_heading_cdeg = saturate_u16(rad_to_deg(sqrt_or_zero(odometry_.est.p(Estimator::kTT))) * 100.0f);
  s.dr_distance_mm = saturate_u16(odometry_.dr_distance_mm);
  s.left_pwm = motion_.left_cmd;
  s.right_pwm = motion_.right_cmd;
  // The decoder's five counters are STATUS's five rx fields, in the same order and width.
  static_assert(sizeof(FrameCounters) == 10 && offsetof(msg::Status, rx_malformed) == offsetof(msg::Status, rx_ok) + 8,
                "FrameCounters lies as STATUS's rx_ok .. rx_malformed");
  memcpy(static_cast<void*>(&s.rx_ok), &decoder_.counters(), sizeof(FrameCounters));
  s.tx_dropped = link_.tx.dropped();
  link_.tx.send(s);
}

// LINK_AUTH in STATUS's place when the refusals have changed since it last went out.
bool Rover::send_link_auth() {
  const AuthCounters& c = link_.auth.counters();
  const uint16_t sum = static_cast<uint16_t>(c.bad_tag + c.replayed + c.not_signed + c.unverified);
  if (sum == link_.auth_reported) return false;
  link_.auth_reported = sum;
  msg::LinkAuth a;
  a.signing = link_.auth.keyed() ? 1 : 0;
  static_assert(sizeof(AuthCounters) == 8 && offsetof(msg::LinkAuth, unverified) == offsetof(msg::LinkAuth, bad_tag) + 6,
                "AuthCounters lies as LINK_AUTH's bad_tag .. unverified");
  memcpy(static_cast<void*>(&a.bad_tag), &c, sizeof c);
  link_.tx.send(a);
  return true;
}

// The OBSTACLE built once and queued `times` times: its copies differ in their sequence number
// only (built afresh for each, the pose's float conversions ran three times in the sweep's step).
ROVERNAV_NOINLINE void Rover::send_reading(int16_t bearing_cdeg, uint16_t range_mm, uint8_t times) {
  msg::Obstacle o;
  o.scan_id = sonar_.scan_id;
  o.bearing_cdeg = bearing_cdeg;
  o.range_mm = range_mm;
  const Point here = here_mm();
  o.x_mm = here.x_mm;
  o.y_mm = here.y_mm;
  o.heading_cdeg = rad_to_cdeg(odometry_.est.heading_rad());
  o.sd_mm = saturate_u16(odometry_.est.position_sd_mm());
  for (uint8_t i = 0; i < times; ++i) link_.tx.send(o);
}

// Left to LTO: kept out of line it cost 4 bytes of flash with avr-gcc 7.3 and 2 with 5.4.
void Rover::report_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  // Said kSayTimes times: the host plans with what it heard, and the rover takes its path on the
  // host's word only when it heard every echo of the sweep (HEARTBEAT's scan_heard). The host
  // drops the copies.
  send_reading(bearing_cdeg, range_mm, kSayTimes);
  sonar_.count_echo();
  remember_echo(bearing_cdeg, range_mm);
}

void Rover::report_clear(int16_t bearing_cdeg) { send_reading(bearing_cdeg, 0, 1); }

}  // namespace core
}  // namespace rovernav
