// The forward reflex: between sweeps the sonar looks ahead while the rover drives, and an echo on
// the path inside the stopping range stops the motors in that step.
#include <doctest.h>

#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {
const core::Waypoint kNorth[] = {{300, 300}, {300, 1400}};

// A rover driving north with its distance-triggered sweeps off, so only the reflex can see.
void drive_north(Bench& b, bool reflex_on) {
  if (!reflex_on) b.config(Param::ReflexPingMs, 0);
  b.without_periodic_sweeps();
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive && b.plant.y_mm > 500.0f; }, 20000));
}
}  // namespace

TEST_CASE("while driving the rover pings about every 60 ms: ahead, right 15 and 30 degrees, ahead, left 15 and 30") {
  Bench b;
  drive_north(b, true);
  int fired = 0, ahead = 0, right = 0, left = 0, wide = 0;
  for (int i = 0; i < 100; ++i) {   // one second
    b.step();
    if (b.out.fire_sonar) {
      ++fired;
      ahead += b.out.servo_cdeg == 0;
      right += b.out.servo_cdeg == 1500;
      left += b.out.servo_cdeg == -1500;
      wide += b.out.servo_cdeg == 3000 || b.out.servo_cdeg == -3000;
    }
  }
  CHECK(fired >= 14);
  CHECK(fired <= 17);
  CHECK(ahead + right + left + wide == fired);
  CHECK(ahead >= fired / 3 - 1);
  CHECK(right >= 2);
  CHECK(left >= 2);
  CHECK(wide >= 4);
}

TEST_CASE("a box corner beside the path, which straight ahead misses, stops the rover") {
  Bench b;
  drive_north(b, true);
  // A box whose corner sits 60 mm to the right of the rover's centre line, 250 mm ahead of the
  // sensor: inside the rover's width, outside the straight-ahead cone at that range.
  const float x0 = b.plant.x_mm + 60.0f, y0 = b.plant.y_mm + 100.0f + 250.0f;
  b.set_box(x0 + 150.0f, y0 + 150.0f, 300.0f, 300.0f);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 10000));
  b.run_ms(300);
  CHECK(b.events(EventKind::Reflex) == 1);
  CHECK(b.closest_to_box_mm > 75.0f);   // the rover's half width: no contact
}

TEST_CASE("a wall appearing ahead stops the rover within its stopping distance, reported, then a sweep") {
  Bench b;
  drive_north(b, true);
  // The range is measured along the way from the edge of the cone farther off the axis. A face
  // straight ahead is within it once within range / cos(7.5 degrees) of the sensor; a side look
  // (30 degrees: its cone's near edge 22.5 degrees off the axis, its far edge 37.5) finds it sooner,
  // within range x cos(22.5) / cos(37.5).
  const float deg = 3.14159265f / 180.0f;
  const float ahead_mm = b.rover.reflex_range_mm() / cosf(7.5f * deg);
  const float widest_mm = b.rover.reflex_range_mm() * cosf(22.5f * deg) / cosf(37.5f * deg);
  MESSAGE("reflex range " << ahead_mm << " mm from the sensor straight ahead, " << widest_mm << " at most");
  // A wall across the path, its face 250 mm ahead of the sensor (the sensor is 100 mm ahead of the centre).
  const float face_y = b.plant.y_mm + 100.0f + 250.0f;
  b.set_box(300.0f, face_y + 50.0f, 600.0f, 100.0f);
  float stopped_at_mm = -1.0f;   // the face's distance from the sensor when the motors stopped
  REQUIRE(b.run_until([&] {
    if (stopped_at_mm < 0.0f && b.out.left_pwm == 0) stopped_at_mm = face_y - (b.plant.y_mm + 100.0f);
    return b.rover.state() == RoverState::Scan;
  }, 10000));
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  MESSAGE("stopped with the face " << stopped_at_mm << " mm from the sensor");
  const float v_mm_s = 2.0f * 40.0f;   // default speed model: 2 mm/s per PWM, 40 PWM above the dead band
  const float stopping_mm = v_mm_s * (60.0f + 150.0f) / 1000.0f;
  // Stopped within the stopping distance of the range straight ahead, not before the widest.
  CHECK(stopped_at_mm >= ahead_mm - stopping_mm);
  CHECK(stopped_at_mm <= widest_mm);
  b.run_ms(300);   // coast to a halt under the sweep
  CHECK(face_y - (b.plant.y_mm + 105.0f) > 0.5f * 100.0f);   // the front still half the margin from the wall
  CHECK(b.events(EventKind::Reflex) == 1);
  msg::Obstacle o;
  REQUIRE(b.count(&o) >= 1);
}

TEST_CASE("without the reflex and without sweeps the same wall is driven into") {
  Bench b;
  drive_north(b, false);
  const float face_y = b.plant.y_mm + 100.0f + 250.0f;
  b.set_box(300.0f, face_y + 50.0f, 600.0f, 100.0f);
  b.run_ms(6000);
  CHECK(b.closest_to_box_mm == doctest::Approx(0.0f));
  CHECK(b.events(EventKind::Reflex) == 0);
}

TEST_CASE("a wall beyond the last waypoint does not stop the rover: the goal in front of it is reached") {
  Bench b;
  b.without_periodic_sweeps();
  const core::Waypoint short_north[] = {{300, 300}, {300, 800}};
  b.set_box(300.0f, 800.0f + 170.0f + 50.0f, 600.0f, 100.0f);   // face 170 mm past the goal
  b.start_mission(short_north, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 30000));
  CHECK(b.events(EventKind::Reflex) == 0);
}

TEST_CASE("a small box whose corner is inside the rover's width stops it, wherever the pings fall") {
  // An 80 mm box met at 20 degrees, its nearest corner 67 mm left of the centre line (the half
  // width is 75), at every phase of the pings' six-look cycle. The 30-degree look sees the corner
  // last at its cone's outer edge: judged from its axis, the corner lay beyond the stopping range
  // until it had left the cone (seed-small-obstacles, the link out, seed 5744, mirrored here).
  const float deg = 3.14159265f / 180.0f;
  const float fx = sinf(20.0f * deg), fy = cosf(20.0f * deg);   // the heading's unit vector
  const core::Waypoint kNorthEast[] = {{300, 300}, {static_cast<int16_t>(300 + 1500 * fx), static_cast<int16_t>(300 + 1500 * fy)}};
  int stopped = 0, cases = 0;
  for (int ahead_mm = 200; ahead_mm < 320; ahead_mm += 7) {
    Bench b;
    b.without_periodic_sweeps();
    b.start_mission(kNorthEast, 2);
    REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Drive && b.plant.y_mm > 450.0f; }, 20000));
    // The corner (the box's right, lower one): ahead of the sensor, 67 mm to the left.
    const float sx = b.plant.x_mm + 100.0f * fx, sy = b.plant.y_mm + 100.0f * fy;
    const float cx = sx + static_cast<float>(ahead_mm) * fx - 67.0f * fy;
    const float cy = sy + static_cast<float>(ahead_mm) * fy + 67.0f * fx;
    b.set_box(cx - 40.0f, cy + 40.0f, 80.0f, 80.0f);
    b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 6000);
    b.run_ms(300);
    ++cases;
    stopped += b.events(EventKind::Reflex) >= 1;
    CHECK_MESSAGE(b.closest_to_box_mm > 0.0f, "box corner " << ahead_mm << " mm ahead of the sensor: contact");
  }
  MESSAGE(stopped << " of " << cases << " stopped by the reflex");
  CHECK(stopped == cases);
}

TEST_CASE("a side look judges the stopping range from its cone's outer edge") {
  // An echo at 30 degrees is anywhere from 22.5 to 37.5 degrees off the way; farther off, it is
  // nearer along it. 139 mm at 30 degrees: 120 mm along on the axis, beyond the range (117 mm
  // here), but 110 mm at the outer edge: it stops the rover. 160 mm (127 mm at the edge) does not.
  const float deg = 3.14159265f / 180.0f;
  const uint16_t kRangesMm[] = {139, 160};
  for (const uint16_t range_mm : kRangesMm) {
    Bench b;
    drive_north(b, true);
    const float along_mm = static_cast<float>(range_mm) * cosf(37.5f * deg);
    b.echo_look_cdeg = 3000;
    b.sonar_range_mm = range_mm;
    b.run_ms(1000);
    const bool within = along_mm <= b.rover.reflex_range_mm();
    MESSAGE(range_mm << " mm at 30 degrees: " << along_mm << " mm along at the outer edge, range " << b.rover.reflex_range_mm());
    CHECK(within == (range_mm == 139));
    CHECK(b.events(EventKind::Reflex) == (within ? 1 : 0));
  }
}
