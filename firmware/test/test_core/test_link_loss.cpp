// Without fixes (camera gone) or without any frame (radio gone) the rover carries on by dead
// reckoning, says which it is, stops safely before its position is too uncertain, and resumes.
#include <doctest.h>
#include <math.h>

#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {
const core::Waypoint kLong[] = {{300, 300}, {300, 2300}};

void no_sweeps(Bench& b) {
  b.config(Param::SweepIntervalMm, 0);
  b.run_ms(20);
}

// Fixes and heartbeats streaming, no periodic sweeps, the rover half a second into its drive.
void driving_with_radio(Bench& b) {
  b.stream_fixes = true;
  b.heartbeats = true;
  b.start_mission(kLong, 2);
  no_sweeps(b);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.run_ms(500);
}
}  // namespace

TEST_CASE("radio lost mid-drive: the rover keeps driving on dead reckoning and says so") {
  Bench b;
  driving_with_radio(b);
  b.radio = false;
  b.run_ms(1500);
  CHECK(b.rover.state() == RoverState::Drive);
  CHECK(b.out.left_pwm > 0);
  CHECK((b.rover.flags() & StatusFlag::RadioLost) != 0);
  CHECK((b.rover.flags() & StatusFlag::DeadReckoning) != 0);
  CHECK((b.rover.flags() & StatusFlag::CameraLost) == 0);  // no radio, not no camera
  const float err = hypotf(b.rover.estimator().x_mm() - b.plant.x_mm, b.rover.estimator().y_mm() - b.plant.y_mm);
  CHECK(err < 20.0f);
  b.radio = true;
  b.run_ms(300);
  CHECK((b.rover.flags() & StatusFlag::RadioLost) == 0);
  CHECK(b.events(EventKind::LinkBack) == 1);
  CHECK(b.events(EventKind::CameraBack) == 1);
}

TEST_CASE("when the radio comes back mid-mission the rover sweeps before it moves on, and the host hears it") {
  Bench b;
  driving_with_radio(b);
  b.radio = false;   // what the rover reports now is lost, and the host's map misses it
  b.sonar_range_mm = 250;   // something to report from here on
  b.run_ms(1500);
  REQUIRE(b.rover.state() == RoverState::Drive);
  b.said_count = 0;   // count what the host hears from here on
  b.radio = true;
  REQUIRE(b.run_until([&] { return b.events(EventKind::LinkBack) == 1; }, 1000));
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 200));
  CHECK(b.out.left_pwm == 0);
  REQUIRE(b.run_until([&] { return b.events(EventKind::ScanDone) >= 1; }, 3000));
  CHECK(b.count<msg::Obstacle>() >= 13);   // the whole sweep, heard
}

TEST_CASE("camera lost while heartbeats arrive: flagged as no camera, with an EVENT") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;
  b.start_mission(kLong, 2);
  no_sweeps(b);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.camera = false;
  b.run_ms(800);
  CHECK((b.rover.flags() & StatusFlag::CameraLost) != 0);
  CHECK((b.rover.flags() & StatusFlag::RadioLost) == 0);
  CHECK(b.events(EventKind::CameraLost) == 1);
  CHECK(b.rover.state() == RoverState::Drive);
}

TEST_CASE("an outage too long to trust: the rover holds before 2 sigma exceeds the clearance margin, then resumes") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;
  b.plant.mm_s_per_pwm = 2.1f;  // the model is 5 % off: dead reckoning drifts
  b.start_mission(kLong, 2);
  no_sweeps(b);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.camera = false;
  float worst_2sd_moving = 0;
  while (b.rover.state() != RoverState::Hold && b.now_ms < 120000) {
    b.step();
    if (b.out.left_pwm != 0 || b.out.right_pwm != 0)
      worst_2sd_moving = fmaxf(worst_2sd_moving, 2.0f * b.rover.estimator().position_sd_mm());
  }
  REQUIRE(b.rover.state() == RoverState::Hold);
  const float margin = b.rover.params().clearance_margin_mm();
  MESSAGE("held after " << b.rover.dr_distance_mm() << " mm of dead reckoning, 2 sigma " << worst_2sd_moving << " mm");
  CHECK(worst_2sd_moving < margin);
  CHECK(b.events(EventKind::Hold) == 1);
  b.run_ms(500);
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  b.camera = true;
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 60000));
  CHECK(b.events(EventKind::Resumed) == 1);
  msg::Event back;
  REQUIRE(b.events(EventKind::CameraBack, &back) == 1);
  MESSAGE("dead-reckoning error revealed by the first fix: " << back.arg << " mm");
  CHECK(back.arg < 60);
}

TEST_CASE("dr_max_distance_mm also bounds a dead-reckoned drive") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kLong, 2);
  no_sweeps(b);
  b.config(Param::DrMaxDistanceMm, 200);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.camera = false;
  const float y0 = b.plant.y_mm;
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Hold; }, 30000));
  CHECK(b.plant.y_mm - y0 < 200.0f + test::default_param(Param::ArrivalRadiusMm) + 50.0f);  // the fix timeout, then 200 mm
}

TEST_CASE("STOP wins during an outage of the camera") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kLong, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive; }, 5000));
  b.camera = false;
  b.run_ms(1000);
  msg::Stop st{};
  b.send(st);
  b.step();
  CHECK(b.out.left_pwm == 0);
  CHECK(b.rover.state() == RoverState::Idle);
}
