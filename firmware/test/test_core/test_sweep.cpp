// The sonar sweep: when it runs, where it points, how long it takes, what it reports.
#include <doctest.h>

#include "harness.h"

using namespace rovernav;
using rovernav::core::Sweep;
using rovernav::test::Bench;

namespace {
const core::Waypoint kNorth[] = {{300, 300}, {300, 1400}};
}

TEST_CASE("a sweep runs at the start and every 300 mm driven, stopped, from -90 to +90 degrees in 15-degree steps") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kNorth, 2);
  int16_t fired_at[64];
  int fires = 0;
  float y_at_scan[8];
  int scans = 0;
  int moving_in_scan = 0;
  RoverState last = RoverState::Idle;
  if (b.rover.state() == RoverState::Scan) y_at_scan[scans++] = b.plant.y_mm;   // the look before moving
  last = b.rover.state();
  while (b.rover.state() != RoverState::Arrived && b.now_ms < 120000) {
    b.step();
    if (b.out.fire_sonar && b.rover.state() == RoverState::Scan && fires < 64) fired_at[fires++] = b.out.servo_cdeg;
    if (b.rover.state() == RoverState::Scan) {
      if (b.out.left_pwm != 0 || b.out.right_pwm != 0) ++moving_in_scan;
      if (last != RoverState::Scan && scans < 8) y_at_scan[scans++] = b.plant.y_mm;
    }
    last = b.rover.state();
  }
  REQUIRE(b.rover.state() == RoverState::Arrived);
  CHECK(moving_in_scan == 0);   // stopped while it sweeps
  CHECK(scans == 4);  // before moving, then at 0.3, 0.6 and 0.9 m of the 1.1 m
  CHECK(y_at_scan[0] == doctest::Approx(300.0f).epsilon(0.01));
  for (int i = 1; i < scans; ++i) CHECK(y_at_scan[i] - 300.0f == doctest::Approx(300.0f * static_cast<float>(i)).epsilon(0.1));
  REQUIRE(fires == 52);
  for (int i = 0; i < 13; ++i) CHECK(fired_at[i] == -9000 + 1500 * i);
  CHECK(b.events(EventKind::ScanDone) == 4);
}

TEST_CASE("a sweep takes at most 1.5 s with the default timing (the seed's took 9 s)") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 20000));
  const uint32_t started = b.now_ms;
  REQUIRE(b.run_until([&] { return b.rover.state() != RoverState::Scan; }, 10000));
  const uint32_t took = b.now_ms - started;
  MESSAGE("sweep took " << took << " ms");
  CHECK(took <= 1500);   // 13 pings and the sweep's end in a step of its own
  CHECK(took > 13 * 60);  // 13 pings, never faster than the HC-SR04 allows
}

TEST_CASE("the slew to -90 degrees waits for the servo's travel, and the settling once") {
  const uint16_t step_ms = 90;
  Sweep s;
  s.start(1000, 0, step_ms);
  int16_t servo = 0;
  bool fire = false;
  uint32_t now = 1000;
  while (!fire && now < 3000) {
    s.step(now, false, 0, servo, fire);
    if (!fire) now += 5;
  }
  CHECK(servo == Sweep::kFirstCdeg);
  // Six 15-degree steps: one step's travel and settling, then five more at the servo's speed.
  CHECK(now - 1000 == step_ms + 5 * Sweep::kSlewMsPerStep);
  // A 15-degree step of the sweep itself waits the whole step time.
  s.step(now + 10, true, 300, servo, fire);
  const uint32_t moved_at = now + 10;
  now = moved_at;
  fire = false;
  while (!fire && now < 3000) {
    s.step(now, false, 0, servo, fire);
    if (!fire) now += 5;
  }
  CHECK(servo == Sweep::kFirstCdeg + Sweep::kStepCdeg);
  CHECK(now - moved_at == step_ms);
}

TEST_CASE("echoes within the report range are reported as OBSTACLE with bearing, range and the rover's pose") {
  Bench b;
  b.stream_fixes = true;
  b.sonar_range_mm = 250;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.events(EventKind::ScanDone) == 1; }, 20000));
  msg::Obstacle o;
  REQUIRE(b.count(&o) == 13);
  CHECK(o.range_mm == 250);
  CHECK(o.bearing_cdeg == 9000);
  CHECK(o.scan_id == 1);
  CHECK(o.x_mm == doctest::Approx(b.plant.x_mm).epsilon(0.02));
  CHECK(o.y_mm == doctest::Approx(b.plant.y_mm).epsilon(0.02));
  CHECK(o.sd_mm <= 5);
  msg::Event e;
  b.events(EventKind::ScanDone, &e);
  CHECK(e.arg == 13);
  // Each echo and the SCAN_DONE are said three times, the copies right after it (a lossy radio).
  CHECK(b.copies<msg::Obstacle>() == 2 * 13);
  CHECK(b.copies<msg::Event>() >= 2);
}

TEST_CASE("a ping with no echo within the report range is reported as a clear reading (range 0)") {
  const uint16_t ranges[] = {0, 601, 900};   // nothing, and beyond the 600 mm report range
  for (uint16_t range : ranges) {
    CAPTURE(range);
    Bench b;
    b.stream_fixes = true;
    b.sonar_range_mm = range;
    b.start_mission(kNorth, 2);
    REQUIRE(b.run_until([&] { return b.events(EventKind::ScanDone) == 1; }, 20000));
    msg::Obstacle o;
    CHECK(b.count(&o) == 13);
    CHECK(o.range_mm == 0);
    msg::Event e;
    b.events(EventKind::ScanDone, &e);
    CHECK(e.arg == 0);   // echoes, not readings
  }
}

TEST_CASE("a sonar that never answers costs a timeout per step, and the rover goes on") {
  Bench b;
  b.stream_fixes = true;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 20000));
  // Step the rest by hand, never setting sonar_valid.
  core::Outputs out{};
  core::Inputs in{};
  uint32_t t = b.now_ms;
  for (int i = 0; i < 500 && b.rover.state() == RoverState::Scan; ++i) {
    in.now_ms = t;
    in.gyro_valid = true;
    in.tx_room = kUartBufferBytes;
    b.rover.step(in, out);
    t += 10;
  }
  CHECK(b.rover.state() != RoverState::Scan);
  CHECK(t - b.now_ms < 3000);
  CHECK(b.rover.rx_counters().frames_ok > 0);
}

namespace {
// Runs the mission to its end (60 s at most): how many sweeps began, and the y of the first four.
int sweeps_until_arrived(Bench& b, float* at_y) {
  int sweeps = 0;
  RoverState last = RoverState::Idle;
  while (b.rover.state() != RoverState::Arrived && b.now_ms < 60000) {
    if (b.rover.state() == RoverState::Scan && last != RoverState::Scan) {
      if (sweeps < 4) at_y[sweeps] = b.plant.y_mm;
      ++sweeps;
    }
    last = b.rover.state();
    b.step();
  }
  return sweeps;
}
}  // namespace

TEST_CASE("before a sharp turn on the spot the rover sweeps, unless it has only just swept") {
  Bench b;
  b.without_periodic_sweeps();   // only the looks before moving and before turning
  const core::Waypoint corner[] = {{300, 300}, {300, 700}, {800, 700}};   // north 400 mm, then east
  b.start_mission(corner, 3);
  float at_y[4] = {0, 0, 0, 0};
  const int sweeps = sweeps_until_arrived(b, at_y);
  REQUIRE(b.rover.state() == RoverState::Arrived);
  REQUIRE(sweeps == 2);                                   // before moving, and at the corner
  CHECK(fabsf(at_y[1] - 700.0f) <= 40.0f);   // within the arrival radius of the corner

  Bench off;
  off.config(Param::SweepBeforeTurnDeg, 0);
  off.without_periodic_sweeps();
  off.start_mission(corner, 3);
  REQUIRE(off.run_until([&] { return off.rover.state() == RoverState::Arrived; }, 60000));
  CHECK(off.events(EventKind::ScanDone) == 1);            // only the look before moving
}

TEST_CASE("a sharp turn soon after a sweep that looked the other way is looked round first") {
  // The look before moving faces north; the rover turns about, drives 70 mm south (less than
  // the 100 mm that makes a sweep old) and must turn east there: what is round it now, no beam
  // of that sweep covered (arena 157 turned into a wall's end so).
  Bench b;
  b.without_periodic_sweeps();
  const core::Waypoint about[] = {{300, 300}, {300, 230}, {600, 230}};
  b.start_mission(about, 3);
  float at_y[4] = {0, 0, 0, 0};
  const int sweeps = sweeps_until_arrived(b, at_y);
  REQUIRE(b.rover.state() == RoverState::Arrived);
  REQUIRE(sweeps == 2);                      // before moving, and at the turn after turning about
  CHECK(fabsf(at_y[1] - 230.0f) <= 40.0f);   // at the second waypoint

  // Facing the way the last sweep looked, a turn within 100 mm of it needs no new look.
  Bench same;
  same.without_periodic_sweeps();
  const core::Waypoint on[] = {{300, 300}, {300, 370}, {600, 370}};
  same.start_mission(on, 3);
  REQUIRE(same.run_until([&] { return same.rover.state() == RoverState::Arrived; }, 60000));
  CHECK(same.events(EventKind::ScanDone) == 1);
}

namespace {
/// STOP (as a fleet's host holds a rover), a path from where it stands, and START with `resume`.
void stop_and_start_again(Bench& b, const core::Waypoint* wps, uint8_t n, uint16_t path_id, uint8_t resume) {
  msg::Stop st{};
  st.reason = static_cast<uint8_t>(StopReason::Replanning);
  b.send(st);
  b.run_ms(500);
  REQUIRE(b.rover.state() == RoverState::Idle);
  b.load_path(path_id, wps, n);
  msg::Start s{};
  s.path_id = path_id;
  s.resume = resume;
  b.send(s);
}
}  // namespace

TEST_CASE("a START that resumes after the host's STOP goes on without a sweep, its memory kept; a new START sweeps first") {
  // Facing north with a box ahead and to the right, in the start's sweep and within reach of the
  // corners: the first path runs north, clear of it (no turn); the host stops the rover at once.
  for (int k = 0; k < 2; ++k) {
    const uint8_t resume = k == 0 ? 1 : 0;
    CAPTURE(resume);
    Bench b;
    b.without_periodic_sweeps();
    b.heartbeats = true;
    b.set_box(300.0f + 85.0f + 100.0f, 300.0f + 70.0f + 100.0f, 200.0f, 200.0f);
    b.start_mission(kNorth, 2);
    REQUIRE(b.run_until([&] { return b.events(EventKind::ScanDone) > 0; }, 10000));
    const int scans = b.events(EventKind::ScanDone);
    // Then due south from where it stands: a half turn that would swing a corner into the box.
    const core::Waypoint south[] = {{300, 300}, {300, 50}};
    stop_and_start_again(b, south, 2, 2, resume);
    bool swept = false;
    REQUIRE(b.run_until([&] {
      swept = swept || b.rover.state() == RoverState::Scan;
      return b.rover.state() == RoverState::BackOff || b.rover.state() == RoverState::Arrived;
    }, 30000));
    // Either way it backs out before the turn: resumed, on what it remembers of the first sweep
    // (it swept nothing since); started anew, on what its new sweep saw.
    CHECK(b.rover.state() == RoverState::BackOff);
    CHECK(swept == (resume == 0));
    CHECK(b.events(EventKind::ScanDone) == scans + (resume == 0 ? 1 : 0));
  }
}
