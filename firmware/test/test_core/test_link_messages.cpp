// The rover's side of the link: HELLO, PATH loading and its refusals, START/STOP, CONFIG,
// STATUS, and bytes that are not frames.
#include <doctest.h>

#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {
const core::Waypoint kLine[] = {{300, 300}, {300, 700}, {300, 1100}};
}

TEST_CASE("at boot the rover says HELLO with its schema hash and boot id, then a boot EVENT") {
  Bench b;
  b.step();
  msg::Hello h;
  REQUIRE(b.count(&h) == 1);
  CHECK(h.schema_hash == kSchemaHash);
  CHECK(h.boot_id == 0xB007);
  CHECK(h.role == static_cast<uint8_t>(Role::Rover));
  CHECK(h.max_waypoints == kMaxWaypoints);
  msg::Event e;
  CHECK(b.events(EventKind::Boot, &e) == 1);
  CHECK(e.arg == 1);
}

TEST_CASE("a host HELLO is answered and, with our schema hash, sets schema_ok") {
  Bench b;
  b.step();
  b.forget_said();
  b.hello();
  b.run_ms(20);
  CHECK(b.count<msg::Hello>() == 1);
  CHECK((b.rover.flags() & StatusFlag::SchemaOk) != 0);
}

TEST_CASE("START is refused with the reason until HELLO, fix and path are all there") {
  Bench b;
  msg::Nack n;
  msg::Start s{};
  s.path_id = 1;

  b.send(s);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::SchemaMismatch));

  msg::Hello other{};
  other.schema_hash = kSchemaHash ^ 1u;
  other.role = static_cast<uint8_t>(Role::Host);
  b.send(other);
  b.send(s);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::SchemaMismatch));

  b.hello();
  b.send(s);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::NoPath));

  b.load_path(7, kLine, 3);
  b.send(s);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::PathIdMismatch));
  CHECK(n.detail == 7);

  s.path_id = 7;
  b.send(s);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::NoFix));

  b.fix_now();
  b.send(s);
  b.run_ms(20);
  CHECK(b.ack_for(b.last_host_seq()));
  CHECK(b.rover.state() == RoverState::Scan);   // a mission begins with a look round
  CHECK((b.rover.flags() & StatusFlag::MissionActive) != 0);
}

TEST_CASE("a 32-waypoint path arrives in four chunks, each ACKed, and is accepted whole") {
  Bench b;
  core::Waypoint wps[32];
  for (uint8_t i = 0; i < 32; ++i) wps[i] = {static_cast<int16_t>(100 + 20 * i), static_cast<int16_t>(200 + 10 * i)};
  b.load_path(42, wps, 32);
  CHECK(b.count<msg::Ack>() == 4);
  CHECK(b.count<msg::Nack>() == 0);
  msg::Event e;
  REQUIRE(b.events(EventKind::PathAccepted, &e) == 1);
  CHECK(e.arg == 42);
  REQUIRE(b.rover.waypoint_count() == 32);
  CHECK(b.rover.waypoint(31).x_mm == 720);
  CHECK(b.rover.waypoint(31).y_mm == 510);
}

struct BadChunk {
  const char* what;
  uint8_t total, first, count;
  int16_t x0;
  NackReason reason;
  uint16_t detail;
};

TEST_CASE("PATH chunks that cannot be taken are NACKed with the reason") {
  const BadChunk cases[] = {
      {"more waypoints than the rover holds", 33, 0, 8, 10, NackReason::TooManyWaypoints, kMaxWaypoints},
      {"an empty path", 0, 0, 1, 10, NackReason::BadValue, 2},
      {"a chunk with no waypoints", 10, 0, 0, 10, NackReason::BadValue, 4},
      {"a chunk running past the total", 10, 8, 8, 10, NackReason::BadValue, 4},
      {"a first chunk that is not the first", 16, 8, 8, 10, NackReason::OutOfOrder, 0},
      {"a negative coordinate", 3, 0, 3, -5, NackReason::BadValue, 0},
  };
  for (const BadChunk& c : cases) {
    CAPTURE(c.what);
    Bench b;
    msg::Path p{};
    p.path_id = 3;
    p.total = c.total;
    p.first_index = c.first;
    p.count = c.count;
    p.x_mm[0] = c.x0;
    b.send(p);
    b.run_ms(20);
    msg::Nack n;
    REQUIRE(b.nack_for(b.last_host_seq(), n));
    CHECK(n.msg_id == msg::Path::kId);
    CHECK(n.reason == static_cast<uint8_t>(c.reason));
    CHECK(n.detail == c.detail);
    CHECK(b.rover.waypoint_count() == 0);
  }
}

TEST_CASE("a chunk skipped in the middle is NACKed as out of order, naming the one expected") {
  Bench b;
  core::Waypoint wps[20] = {};
  for (auto& w : wps) w = {100, 100};
  msg::Path p{};
  p.path_id = 9;
  p.total = 20;
  p.first_index = 0;
  p.count = 8;
  b.send(p);
  p.first_index = 16;
  p.count = 4;
  b.send(p);
  b.run_ms(30);
  msg::Nack n;
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::OutOfOrder));
  CHECK(n.detail == 8);
}

TEST_CASE("a repeated chunk (its ACK was lost) is ACKed again, not refused") {
  Bench b;
  msg::Path p{};
  p.path_id = 5;
  p.total = 10;
  p.count = 8;
  for (uint8_t i = 0; i < 8; ++i) p.x_mm[i] = p.y_mm[i] = static_cast<int16_t>(100 + i);
  b.send(p);
  b.send(p);
  b.run_ms(30);
  CHECK(b.count<msg::Ack>() == 2);
  CHECK(b.count<msg::Nack>() == 0);
  p.first_index = 8;
  p.count = 2;
  b.send(p);
  b.send(p);
  b.run_ms(30);
  CHECK(b.count<msg::Ack>() == 4);
  CHECK(b.count<msg::Nack>() == 0);
  CHECK(b.rover.waypoint_count() == 10);
}

TEST_CASE("CONFIG sets a parameter, and unknown or out-of-range ones are NACKed") {
  Bench b;
  msg::Config c{};
  c.param = static_cast<uint8_t>(Param::DrivePwm);
  c.value = 90;
  b.send(c);
  b.run_ms(20);
  CHECK(b.ack_for(b.last_host_seq()));
  CHECK(b.rover.params().drive_pwm() == doctest::Approx(90.0f));

  msg::Nack n;
  c.value = 300;
  b.send(c);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::ParamOutOfRange));
  CHECK(n.detail == static_cast<uint8_t>(Param::DrivePwm));
  CHECK(b.rover.params().drive_pwm() == doctest::Approx(90.0f));

  c.param = 200;
  c.value = 1;
  b.send(c);
  b.run_ms(20);
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::UnknownParam));
}

TEST_CASE("every parameter of the definition can be set to its limits") {
  for (uint8_t id = 1; id <= kParamMaxId; ++id) {
    int32_t def = 0, lo = 0, hi = 0;
    if (!param_limits(id, def, lo, hi)) continue;
    core::Params p;
    p.reset();
    CAPTURE(id);
    CHECK(p.set(id, lo) == core::SetResult::Ok);
    CHECK(p.set(id, hi) == core::SetResult::Ok);
    CHECK(p.set(id, hi + 1) == core::SetResult::OutOfRange);
    CHECK(p.raw(static_cast<Param>(id)) == hi);
  }
}

TEST_CASE("seed defaults: Kp 30, Ki 3, Kd 5, clamp 130, right bias 0.8, drive 70, cone 18 mm, arrival 36 mm") {
  core::Params p;
  p.reset();
  CHECK(p.kp() == doctest::Approx(30.0f));
  CHECK(p.ki() == doctest::Approx(3.0f));
  CHECK(p.kd() == doctest::Approx(5.0f));
  CHECK(p.pid_out_max_pwm() == doctest::Approx(130.0f));
  CHECK(p.right_bias() == doctest::Approx(0.8f));
  CHECK(p.drive_pwm() == doctest::Approx(70.0f));
  CHECK(p.cone_tol_mm() == doctest::Approx(18.0f));
  CHECK(p.arrival_radius_mm() == doctest::Approx(36.0f));
  CHECK(p.sweep_interval_mm() == doctest::Approx(300.0f));
  CHECK(p.sonar_report_mm() == 600);
}

TEST_CASE("STATUS goes out every status_period_ms with the state, pose and link counters") {
  Bench b;
  b.hello();
  b.fix_now();
  b.run_ms(1000);
  msg::Status s;
  const int n = b.count(&s);
  CHECK(n >= 4);
  CHECK(n <= 6);
  CHECK(s.state == static_cast<uint8_t>(RoverState::Idle));
  CHECK(s.x_mm == 300);
  CHECK(s.y_mm == 300);
  CHECK(s.rx_ok == 2);
  CHECK(s.sd_x_mm <= 3);
  CHECK((s.flags & StatusFlag::SchemaOk) != 0);
}

TEST_CASE("garbage and corrupted frames are counted and ignored; a STOP inside a bad frame is not obeyed") {
  Bench b;
  const core::Waypoint wps[] = {{300, 300}, {300, 1500}};
  b.stream_fixes = true;
  b.start_mission(wps, 2);
  b.run_ms(500);
  REQUIRE((b.rover.flags() & StatusFlag::MissionActive) != 0);
  const uint8_t garbage[] = {0x12, 0x34, 0x00, 0xFF, 0xFE, 0x01, 0x00};
  b.queue(garbage, sizeof garbage);
  uint8_t stop[kMaxEncodedFrame];
  msg::Stop st{};
  const uint8_t n = encode_message(st, 77, stop);
  stop[3] ^= 0x10;  // one flipped bit
  b.queue(stop, n);
  b.run_ms(100);
  CHECK((b.rover.flags() & StatusFlag::MissionActive) != 0);
  const FrameCounters& c = b.rover.rx_counters();
  CHECK(c.bad_crc + c.malformed >= 2);
}

TEST_CASE("STOP always wins: motors off in the same step, mission over, STOP acknowledged") {
  Bench b;
  const core::Waypoint wps[] = {{300, 300}, {300, 1500}};
  b.stream_fixes = true;
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 3000));
  b.run_ms(200);
  REQUIRE(b.out.left_pwm > 0);
  msg::Stop st{};
  st.reason = static_cast<uint8_t>(StopReason::Operator);
  b.send(st);
  b.step();
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  CHECK(b.rover.state() == RoverState::Idle);
  CHECK(b.ack_for(b.last_host_seq()));
  CHECK(b.events(EventKind::Stopped) == 1);
}
