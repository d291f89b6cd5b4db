// A silent or implausible gyro stops the motors within 100 ms, raises a fault EVENT, and
// nothing hangs: the rover keeps stepping, talking and answering.
#include <doctest.h>

#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {
const core::Waypoint kNorth[] = {{300, 300}, {300, 2000}};
}

TEST_CASE("a gyro that goes silent mid-drive stops the motors within 100 ms and raises a fault") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.run_ms(200);
  REQUIRE(b.out.left_pwm != 0);
  b.gyro_alive = false;
  const uint32_t died = b.now_ms;
  REQUIRE(b.run_until([&] { return b.out.left_pwm == 0 && b.out.right_pwm == 0; }, 1000));
  const uint32_t stopped_after = b.now_ms - died;
  MESSAGE("motors stopped " << stopped_after << " ms after the last gyro sample");
  CHECK(stopped_after <= 100);
  CHECK(b.rover.state() == RoverState::Fault);
  CHECK(b.rover.fault() == FaultCode::GyroSilent);
  msg::Event e;
  REQUIRE(b.events(EventKind::Fault, &e) == 1);
  CHECK(e.arg == static_cast<uint16_t>(FaultCode::GyroSilent));
  // Nothing hangs: STATUS keeps coming and says why.
  b.forget_said();
  b.run_ms(1000);
  msg::Status s;
  CHECK(b.count(&s) >= 4);
  CHECK(s.fault == static_cast<uint8_t>(FaultCode::GyroSilent));
  CHECK((s.flags & StatusFlag::GyroFault) != 0);
  CHECK(b.out.left_pwm == 0);
}

TEST_CASE("an implausible gyro rate is a fault at once") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.gyro_override = true;
  b.gyro_override_mdps = 900000;  // 900 deg/s: the rover cannot turn like that
  b.step();
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  CHECK(b.rover.fault() == FaultCode::GyroImplausible);
}

TEST_CASE("START is refused while faulted; the fault clears when the gyro is back, and START works again") {
  Bench b;
  b.stream_fixes = true;
  b.gyro_alive = false;
  b.hello();
  b.run_ms(200);
  REQUIRE(b.rover.fault() == FaultCode::GyroSilent);
  const core::Waypoint wps[] = {{300, 300}, {300, 600}};
  b.load_path(1, wps, 2);
  msg::Start s{};
  s.path_id = 1;
  b.send(s);
  b.run_ms(20);
  msg::Nack n;
  REQUIRE(b.nack_for(b.last_host_seq(), n));
  CHECK(n.reason == static_cast<uint8_t>(NackReason::Faulted));
  b.gyro_alive = true;
  b.run_ms(600);
  CHECK(b.rover.fault() == FaultCode::None);
  CHECK(b.events(EventKind::FaultCleared) == 1);
  b.send(s);
  b.run_ms(20);
  msg::Nack why;
  CHECK_FALSE(b.nack_for(b.last_host_seq(), why));
  CAPTURE(why.reason);
  CHECK(b.ack_for(b.last_host_seq()));
}

TEST_CASE("a rover that never had a gyro reports the fault instead of waiting for it") {
  Bench b;
  b.gyro_alive = false;
  b.run_ms(100);
  CHECK(b.rover.fault() == FaultCode::GyroSilent);
  CHECK(b.count<msg::Hello>() == 1);
  CHECK(b.events(EventKind::Fault) == 1);
}
