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
  const float range_mm = b.rover.reflex_range_mm();
  MESSAGE("reflex range " << range_mm << " mm from the sensor");
  // A wall across the path, its face 250 mm ahead of the sensor (the sensor is 100 mm ahead of the centre).
  const float face_y = b.plant.y_mm + 100.0f + 250.0f;
  b.set_box(300.0f, face_y + 50.0f, 600.0f, 100.0f);
  float y_at_range = -1.0f;
  REQUIRE(b.run_until([&] {
    if (y_at_range < 0.0f && face_y - (b.plant.y_mm + 100.0f) <= range_mm) y_at_range = b.plant.y_mm;
    return b.rover.state() == RoverState::Scan;
  }, 10000));
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  b.run_ms(300);   // coast to a halt under the sweep
  const float v_mm_s = 2.0f * 40.0f;   // default speed model: 2 mm/s per PWM, 40 PWM above the dead band
  const float stopping_mm = v_mm_s * (60.0f + 150.0f) / 1000.0f;
  REQUIRE(y_at_range > 0.0f);
  CHECK(b.plant.y_mm - y_at_range <= stopping_mm);
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
