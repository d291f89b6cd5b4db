// A test bench for the rover core: an injected clock, a little differential-drive plant that
// closes the loop (gyro rate and position from the motor commands), a host that sends frames,
// and a decoder that collects everything the rover says. No sleeps: time is a number.
#pragma once
#include <math.h>
#include <string.h>

#include "frame.h"
#include "frame_auth.h"
#include "angles.h"
#include "sonar_geometry.h"
#include "rover.h"

namespace rovernav {
namespace test {

/// A parameter's default, from the protocol definition (messages.toml, generated).
inline float default_param(Param p) {
  int32_t def = 0, lo = 0, hi = 0;
  param_limits(static_cast<uint8_t>(p), def, lo, hi);
  return static_cast<float>(def);
}

/// Where a rover that has arrived may stand from its goal: the arrival radius (the protocol's
/// default) and 10 mm of coasting after the motors stop.
inline float arrived_within_mm() { return default_param(Param::ArrivalRadiusMm) + 10.0f; }

struct Said {
  uint8_t msg_id;
  uint8_t seq;
  uint8_t len;
  uint8_t payload[kMaxPayload];
};

/// A differential drive: speed from the mean PWM above the dead band, yaw rate from the
/// difference, each wheel following its command with a first-order lag (motor and inertia);
/// a right motor `right_gain` as strong as the left (the seed's was stronger).
struct Plant {
  float lag_s = 0.08f;
  float left_eff = 0, right_eff = 0;
  float x_mm = 300, y_mm = 300, heading_rad = 0;
  float mm_s_per_pwm = default_param(Param::SpeedMmSPerPwmX1000) / 1000.0f;   // the core's speed model
  float deg_s_per_pwm = 1.2f;      // yaw rate per PWM of wheel difference
  float right_gain = 1.0f;
  int16_t deadband = static_cast<int16_t>(default_param(Param::MotorDeadbandPwm));
  float rate_dps = 0;
  void advance(int16_t left, int16_t right, float dt_s) {
    const float k = dt_s / (lag_s + dt_s);
    left_eff += k * (eff(left) - left_eff);
    right_eff += k * (eff(right) * right_gain - right_eff);
    const float l = left_eff, r = right_eff;
    const float v = mm_s_per_pwm * 0.5f * (l + r);
    rate_dps = deg_s_per_pwm * 0.5f * (l - r);
    const float mid = heading_rad + 0.5f * rate_dps * 0.0174533f * dt_s;
    x_mm += v * dt_s * sinf(mid);
    y_mm += v * dt_s * cosf(mid);
    heading_rad += rate_dps * 0.0174533f * dt_s;
  }
  float eff(int16_t pwm) const {
    const int m = pwm < 0 ? -pwm : pwm;
    if (m <= deadband) return 0;
    return static_cast<float>(pwm < 0 ? -(m - deadband) : (m - deadband));
  }
  int16_t heading_cdeg() const { return core::rad_to_cdeg(heading_rad); }
};

class Bench {
 public:
  // What the line brings in one step: 10 bits a byte (8N1).
  enum : uint16_t { kRxPerStep = static_cast<uint32_t>(kLinkBaud) / 10 * kStepPeriodMs / 1000 };
  core::Rover rover;
  Plant plant;
  uint32_t now_ms = 1000;
  uint16_t step_ms = kStepPeriodMs;
  bool gyro_alive = true;
  int32_t gyro_override_mdps = 0;
  bool gyro_override = false;
  bool radio = true;            // bytes reach the rover
  bool camera = true;           // fixes are sent (when stream_fixes)
  bool stream_fixes = false;    // a FIX every fix_period_ms from the plant's true pose
  uint16_t fix_period_ms = 33;
  bool heartbeats = false;
  uint8_t address = 0;          // the rover's address the host talks to and listens for ([fleet]; 0 alone)
  // The host's word in its HEARTBEATs: it heard every sweep whole (scan_heard: the last sweep whose
  // SCAN_DONE it was said) and holds the last path loaded; false: it heard none (a lossy radio).
  bool hears_sweeps = true;
  uint16_t scan_heard = 0, last_scan_seen = 0, host_path_id = 0;
  uint16_t sonar_range_mm = 0;  // what the next ping returns (0 = nothing), unless a box is set
  int16_t echo_look_cdeg = -1;  // >= 0: only pings looking this way return sonar_range_mm
  bool has_box = false;         // an obstacle in the world: the sonar sees it, the host does not
  float box_x0 = 0, box_y0 = 0, box_x1 = 0, box_y1 = 0;
  float closest_to_box_mm = 1e9f;  // nearest the rover's centre came to the box
  void set_box(float cx, float cy, float w, float h) {
    has_box = true;
    box_x0 = cx - w / 2;
    box_x1 = cx + w / 2;
    box_y0 = cy - h / 2;
    box_y1 = cy + h / 2;
  }
  /// The ping's range: the box along the beam's axis (and +-7.5 degrees), within 1 m; else 0.
  uint16_t ping(int16_t servo_cdeg) const {
    if (!has_box) return echo_look_cdeg < 0 || servo_cdeg == echo_look_cdeg ? sonar_range_mm : 0;
    const float h = plant.heading_rad;
    const core::PointMm s = core::sonar_origin(plant.x_mm, plant.y_mm, h, default_param(Param::SonarOffsetMm));
    const float sx = s.x_mm, sy = s.y_mm;
    // Five rays across the cone (the parameter's full width), as the simulator's ranger casts more.
    const float quarter_cone_cdeg = default_param(Param::SonarConeCdeg) / 4.0f;
    float best = 1e9f;
    for (int k = -2; k <= 2; ++k) {
      const float a = h + core::cdeg_to_rad(static_cast<int32_t>(servo_cdeg + quarter_cone_cdeg * static_cast<float>(k)));
      const float dx = sinf(a), dy = cosf(a);
      float t0 = 0.0f, t1 = 1e9f;
      bool hit = true;
      const float lo[2] = {box_x0, box_y0}, hi[2] = {box_x1, box_y1}, p[2] = {sx, sy}, d[2] = {dx, dy};
      for (int i = 0; i < 2 && hit; ++i) {
        if (fabsf(d[i]) < 1e-9f) {
          hit = p[i] >= lo[i] && p[i] <= hi[i];
          continue;
        }
        float ta = (lo[i] - p[i]) / d[i], tb = (hi[i] - p[i]) / d[i];
        if (ta > tb) { const float t = ta; ta = tb; tb = t; }
        t0 = fmaxf(t0, ta);
        t1 = fminf(t1, tb);
        hit = t0 <= t1;
      }
      if (hit && t0 < best) best = t0;
    }
    return best < 1000.0f ? static_cast<uint16_t>(best) : 0;
  }
  uint32_t pings = 0;
  core::Outputs out{};
  Said said[512];
  int said_count = 0;

  Bench() { rover.begin(0xB007, 1); }

  /// Sends a command; last_host_seq() then names it (streamed fixes and heartbeats do not).
  template <typename Msg>
  void send(const Msg& m) {
    last_cmd_seq_ = host_seq_;
    send_auto(m);
  }
  void queue(const uint8_t* bytes, uint16_t n) {
    for (uint16_t i = 0; i < n && rx_len_ < sizeof rx_; ++i) rx_[rx_len_++] = bytes[i];
  }
  uint8_t last_host_seq() const { return last_cmd_seq_; }
  /// Sends CONFIG {param, value}.
  void config(Param p, int32_t value) {
    msg::Config c{};
    c.param = static_cast<uint8_t>(p);
    c.value = value;
    send(c);
  }

  void hello() {
    msg::Hello h{};
    h.schema_hash = kSchemaHash;
    h.role = static_cast<uint8_t>(Role::Host);
    send(h);
  }
  /// Fixes streamed, HELLO said, and no sweep every sweep_interval_mm (only the looks before
  /// moving and before sharp turns): for tests about what the rover does between sweeps.
  void without_periodic_sweeps() {
    stream_fixes = true;
    hello();
    config(Param::SweepIntervalMm, 0);
    run_ms(50);
  }
  void fix_now(int16_t sd_mm = 2) { send(fix_msg(sd_mm)); }
  msg::Fix fix_msg(int16_t sd_mm = 2) const {
    msg::Fix f{};
    f.x_mm = static_cast<int16_t>(lroundf(plant.x_mm));
    f.y_mm = static_cast<int16_t>(lroundf(plant.y_mm));
    f.heading_cdeg = plant.heading_cdeg();
    f.sd_mm = static_cast<uint8_t>(sd_mm);
    return f;
  }
  /// Sends a path (in chunks of 8) and runs until every chunk is answered.
  void load_path(uint16_t path_id, const core::Waypoint* wps, uint8_t n, uint8_t back_out = 0) {
    host_path_id = path_id;
    for (uint8_t first = 0; first < n; first = static_cast<uint8_t>(first + kWaypointsPerChunk)) {
      msg::Path p{};
      p.path_id = path_id;
      p.total = n;
      p.back_out = back_out;
      p.first_index = first;
      p.count = static_cast<uint8_t>(n - first < kWaypointsPerChunk ? n - first : kWaypointsPerChunk);
      for (uint8_t i = 0; i < p.count; ++i) {
        p.x_mm[i] = wps[first + i].x_mm;
        p.y_mm[i] = wps[first + i].y_mm;
      }
      send(p);
      run_ms(20);
    }
  }
  /// HELLO, a fix, the path (its chunks carrying back_out), START: a mission under way.
  void start_mission(const core::Waypoint* wps, uint8_t n, uint16_t path_id = 1, uint8_t back_out = 0) {
    hello();
    fix_now();
    run_ms(20);
    load_path(path_id, wps, n, back_out);
    msg::Start s{};
    s.path_id = path_id;
    send(s);
    run_ms(20);
  }

  void step() {
    core::Inputs in{};
    in.now_ms = now_ms;
    in.gyro_valid = gyro_alive;
    in.gyro_rate_mdps = gyro_override ? gyro_override_mdps : static_cast<int32_t>(lroundf(plant.rate_dps * 1000.0f));
    in.sonar_valid = pending_ping_;
    in.sonar_range_mm = ping_result_;
    pending_ping_ = false;
    if (stream_fixes && camera && now_ms - last_fix_ms_ >= fix_period_ms) {
      last_fix_ms_ = now_ms;
      send_auto(fix_msg());
    }
    if (heartbeats && now_ms - last_hb_ms_ >= 200) {
      last_hb_ms_ = now_ms;
      msg::Heartbeat h{};
      h.host_time_ms = now_ms;
      h.camera = static_cast<uint8_t>(camera ? CameraState::Ok : CameraState::NoRover);
      h.scan_heard = scan_heard;
      h.path_id = host_path_id;
      send_auto(h);
    }
    // The line brings about kRxPerStep bytes in a step (57 at 57,600 baud); the rest waits for the next one.
    const uint16_t chunk = rx_len_ < kRxPerStep ? rx_len_ : static_cast<uint16_t>(kRxPerStep);
    in.rx = rx_;
    in.rx_len = radio ? static_cast<uint8_t>(chunk) : 0;
    in.tx_room = kUartBufferBytes;
    rover.step(in, out);
    memmove(rx_, rx_ + chunk, rx_len_ - chunk);
    rx_len_ = static_cast<uint16_t>(rx_len_ - chunk);
    if (out.fire_sonar) {
      pending_ping_ = true;
      ping_result_ = ping(out.servo_cdeg);
      ++pings;
    }
    for (uint8_t i = 0; i < out.tx_len; ++i) {
      if (radio && decoder_.push(out.tx[i], static_cast<uint8_t>(address << kAddressShift)) && said_count < 512) {
        Said& s = said[said_count++];
        s.msg_id = decoder_.frame().msg_id;
        s.seq = decoder_.frame().seq;
        s.len = decoder_.frame().payload_len;
        memcpy(s.payload, decoder_.frame().payload, s.len);
        if (s.msg_id == msg::Obstacle::kId) {
          msg::Obstacle o;
          o.decode(s.payload);
          last_scan_seen = o.scan_id;
        } else if (s.msg_id == msg::Event::kId && hears_sweeps) {
          msg::Event e;
          e.decode(s.payload);
          if (e.kind == static_cast<uint8_t>(EventKind::ScanDone)) scan_heard = last_scan_seen;
        }
      }
    }
    plant.advance(out.left_pwm, out.right_pwm, static_cast<float>(step_ms) / 1000.0f);
    if (has_box) {
      const float dx = fmaxf(fmaxf(box_x0 - plant.x_mm, 0.0f), plant.x_mm - box_x1);
      const float dy = fmaxf(fmaxf(box_y0 - plant.y_mm, 0.0f), plant.y_mm - box_y1);
      closest_to_box_mm = fminf(closest_to_box_mm, sqrtf(dx * dx + dy * dy));
    }
    now_ms += step_ms;
  }
  void run_ms(uint32_t ms) {
    const uint32_t end = now_ms + ms;
    while (static_cast<int32_t>(end - now_ms) > 0) step();
  }
  /// Runs until pred() or the time limit; returns whether pred() came true.
  template <typename Pred>
  bool run_until(Pred pred, uint32_t limit_ms) {
    const uint32_t end = now_ms + limit_ms;
    while (static_cast<int32_t>(end - now_ms) > 0) {
      step();
      if (pred()) return true;
    }
    return false;
  }

  /// How many messages of type Msg the rover has said; `last` gets the latest.
  template <typename Msg>
  int count(Msg* last = nullptr) const {
    int n = 0;
    for (int i = 0; i < said_count; ++i) {
      if (said[i].msg_id == Msg::kId && !copy_of_previous(i)) {
        ++n;
        if (last) last->decode(said[i].payload);
      }
    }
    return n;
  }
  /// Whether message i is a copy of the one said just before it (the rover says each echo and
  /// SCAN_DONE twice): count() and events() count such a pair once; copies() counts the copies.
  bool copy_of_previous(int i) const {
    return i > 0 && said[i - 1].msg_id == said[i].msg_id && said[i - 1].len == said[i].len &&
           memcmp(said[i - 1].payload, said[i].payload, said[i].len) == 0;
  }
  template <typename Msg>
  int copies() const {
    int n = 0;
    for (int i = 0; i < said_count; ++i) n += said[i].msg_id == Msg::kId && copy_of_previous(i);
    return n;
  }
  int events(EventKind kind, msg::Event* last = nullptr) const {
    int n = 0;
    for (int i = 0; i < said_count; ++i) {
      if (said[i].msg_id != msg::Event::kId || copy_of_previous(i)) continue;
      msg::Event e;
      e.decode(said[i].payload);
      if (e.kind == static_cast<uint8_t>(kind)) {
        ++n;
        if (last) *last = e;
      }
    }
    return n;
  }
  /// The NACK answering host frame `seq`, if any.
  bool nack_for(uint8_t seq, msg::Nack& n) const {
    for (int i = 0; i < said_count; ++i) {
      if (said[i].msg_id != msg::Nack::kId) continue;
      n.decode(said[i].payload);
      if (n.seq == seq) return true;
    }
    return false;
  }
  bool ack_for(uint8_t seq) const {
    for (int i = 0; i < said_count; ++i) {
      if (said[i].msg_id != msg::Ack::kId) continue;
      msg::Ack a;
      a.decode(said[i].payload);
      if (a.seq == seq) return true;
    }
    return false;
  }
  void forget_said() { said_count = 0; }
  float true_distance_to(float x, float y) const { return hypotf(plant.x_mm - x, plant.y_mm - y); }

 private:
  template <typename Msg>
  void send_auto(const Msg& m) {
    uint8_t payload[Msg::kPayloadSize];
    m.encode(payload);
    FrameAuth host;   // no key: the host's frames unsigned, to the rover at `address`
    host.set_address(address);
    uint8_t buf[kMaxEncodedFrame];
    const uint8_t n = encode_frame(Msg::kId, host_seq_++, payload, Msg::kPayloadSize, buf, &host);
    queue(buf, n);
  }

  uint8_t last_cmd_seq_ = 0;
  uint8_t rx_[4096];
  uint16_t rx_len_ = 0;
  uint8_t host_seq_ = 0;
  bool pending_ping_ = false;
  uint16_t ping_result_ = 0;
  uint32_t last_fix_ms_ = 0;
  uint32_t last_hb_ms_ = 0;
  FrameDecoder decoder_;
};

}  // namespace test
}  // namespace rovernav
