// Frames to the host, queued whole (TxQueue): ACK and NACK, HELLO, EVENT, STATUS, and the
// sonar's readings as OBSTACLE frames.
#include "rover.h"

#include "angles.h"
#include "float_ops.h"

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
  msg::Hello h{};   // signing 0: this rover holds no key yet (issue 14)
  h.schema_hash = kSchemaHash;
  h.boot_id = boot_id_;
  h.firmware_version = kFirmwareVersion;
  h.role = static_cast<uint8_t>(Role::Rover);
  h.max_waypoints = kMaxWaypoints;
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
  s.state = static_cast<uint8_t>(state_);
  s.flags = flags();
  s.fault = static_cast<uint8_t>(fault_);
  s.path_id = path_id_;
  s.waypoint_index = wp_;
  const Point here = here_mm();
  s.x_mm = here.x_mm;
  s.y_mm = here.y_mm;
  s.heading_cdeg = rad_to_cdeg(est_.heading_rad());
  const float sd_x = sqrt_or_zero(est_.p(0)), sd_y = sqrt_or_zero(est_.p(3));
  s.sd_x_mm = saturate_u16(sd_x);
  s.sd_y_mm = saturate_u16(sd_y);
  const float denom = sd_x * sd_y;
  s.corr_xy_permille = denom > 0.0f ? saturate_i16(1000.0f * est_.p(1) / denom) : 0;
  s.sd_heading_cdeg = saturate_u16(sqrt_or_zero(est_.p(5)) * kDegPerRad * 100.0f);
  s.dr_distance_mm = saturate_u16(dr_distance_mm_);
  s.fix_age_ms = had_fix_ ? saturate_u16(static_cast<float>(last_ms_ - last_fix_ms_)) : 65535;
  s.left_pwm = left_cmd_;
  s.right_pwm = right_cmd_;
  const FrameCounters& c = decoder_.counters();
  s.rx_ok = c.frames_ok;
  s.rx_bad_crc = c.bad_crc;
  s.rx_overlong = c.overlong;
  s.rx_unknown_id = c.unknown_id;
  s.rx_malformed = c.malformed;
  s.tx_dropped = tx_.dropped();
  tx_.send(s);
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

void Rover::report_echo(int16_t bearing_cdeg, uint16_t range_mm) {
  send_reading(bearing_cdeg, range_mm);
  ++scan_echoes_;
  remember_echo(bearing_cdeg, range_mm);
}

void Rover::report_clear(int16_t bearing_cdeg) { send_reading(bearing_cdeg, 0); }

}  // namespace core
}  // namespace rovernav
