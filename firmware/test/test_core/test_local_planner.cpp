// The rover's own detour: the wavefront planner on its small grid, planned in slices, and the
// rover getting round an obstacle its sonar found with no help from the host.
#include <doctest.h>
#include <math.h>

#include "harness.h"
#include "local_planner.h"

using namespace rovernav;
using rovernav::core::LocalPlanner;
using rovernav::core::Point;
using rovernav::test::Bench;

namespace {

bool detour_clear(const LocalPlanner& lp, Point start, const Point* wps, uint8_t n) {
  Point a = start;
  for (uint8_t i = 0; i < n; ++i) {
    if (lp.blocks(a, wps[i])) return false;
    a = wps[i];
  }
  return true;
}

}  // namespace

TEST_CASE("a disk on the leg: the planner finds a clear way round") {
  LocalPlanner lp;
  lp.clear();
  const Point start{300, 300}, goal{300, 1000};
  lp.add(Point{300, 700}, 230, start);  // an echo 0.4 m ahead with its clearance and beam width
  lp.add(Point{340, 700}, 230, start);
  uint8_t scratch[LocalPlanner::kScratchBytes];
  Point out[LocalPlanner::kMaxDetour];
  REQUIRE(lp.blocks(start, goal));
  const uint8_t n = lp.plan(start, goal, scratch, out);
  REQUIRE(n >= 2);
  CHECK(out[n - 1].x_mm == goal.x_mm);
  CHECK(out[n - 1].y_mm == goal.y_mm);
  CHECK(detour_clear(lp, start, out, n));
  CHECK(LocalPlanner::kScratchBytes <= 128);
}

// The Uno's time per slice is measured on the image in the AVR simulator; here, that the work
// is cut into slices at all, each bounded by one layer of the wavefront, and that the result
// is the one planned in one go.
TEST_CASE("planned in slices, a step each: the same detour, no slice more than one wavefront layer") {
  LocalPlanner lp;
  lp.clear();
  for (int16_t i = 0; i < 9; ++i) lp.add(Point{static_cast<int16_t>(100 + 60 * i), static_cast<int16_t>(650 + (i % 2) * 60)}, 120, Point{300, 300});
  uint8_t scratch[LocalPlanner::kScratchBytes];
  Point whole[LocalPlanner::kMaxDetour];
  const Point start{300, 300}, goal{300, 1000};
  const uint8_t n_whole = lp.plan(start, goal, scratch, whole);
  REQUIRE(n_whole >= 2);

  Point out[LocalPlanner::kMaxDetour];
  REQUIRE(lp.begin(start, goal, scratch));
  uint8_t n = 0;
  unsigned slices = 0;
  uint16_t ops_before = 0;
  uint32_t max_slice_ops = 0;
  core::PlanStatus st = core::PlanStatus::Running;
  while (st == core::PlanStatus::Running && slices < 1000) {
    st = lp.step(scratch, out, n);
    ++slices;
    const uint16_t slice_ops = static_cast<uint16_t>(lp.ops() - ops_before);
    ops_before = lp.ops();
    if (slice_ops > max_slice_ops) max_slice_ops = slice_ops;
  }
  MESSAGE(slices << " slices, at most " << max_slice_ops << " operations in one");
  REQUIRE(st == core::PlanStatus::Found);
  CHECK(slices >= 6);   // 144 cells marked 36 at a time, then one slice per layer and the walk
  CHECK(max_slice_ops <= 9u * LocalPlanner::kCellCount);   // one layer: every cell, eight neighbours
  REQUIRE(n == n_whole);
  for (uint8_t i = 0; i < n; ++i) {
    CHECK(out[i].x_mm == whole[i].x_mm);
    CHECK(out[i].y_mm == whole[i].y_mm);
  }
  CHECK_FALSE(lp.planning());
}

TEST_CASE("while the rover plans its own detour it keeps stepping: STOP is served at once") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;   // a host that heard every sweep and holds its path: it does not replan
  b.set_box(300, 1050, 200, 200);  // dead ahead; no path comes from the host
  const core::Waypoint wps[] = {{300, 300}, {300, 1600}};
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.planning_detour(); }, 60000));
  b.step();
  CHECK(b.rover.planning_detour());   // more than one step
  CHECK(b.out.left_pwm == 0);
  CHECK(b.out.right_pwm == 0);
  msg::Stop stop{};
  b.send(stop);
  b.step();
  CHECK(b.rover.state() == RoverState::Idle);
  CHECK_FALSE(b.rover.planning_detour());
  msg::Ack ack{};
  REQUIRE(b.count(&ack) >= 1);
  CHECK(ack.msg_id == msg::Stop::kId);
}

TEST_CASE("no way round on the grid: the planner says so instead of guessing") {
  LocalPlanner lp;
  lp.clear();
  for (int16_t i = 0; i < 9; ++i) lp.add(Point{static_cast<int16_t>(-200 + 110 * i), 650}, 200, Point{300, 300});  // a wall
  uint8_t scratch[LocalPlanner::kScratchBytes];
  Point out[LocalPlanner::kMaxDetour];
  CHECK(lp.plan(Point{300, 300}, Point{300, 1000}, scratch, out) == 0);
  CHECK(lp.plan(Point{300, 300}, Point{300, 650}, scratch, out) == 0);  // the goal itself is blocked
}

TEST_CASE("the rover gets round an obstacle its sonar found, with no new path from the host") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;   // a host that heard every sweep and holds its path: it does not replan
  b.set_box(300, 1050, 200, 200);  // dead ahead on the leg; the host's path runs through it
  const core::Waypoint wps[] = {{300, 300}, {300, 1600}};
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 120000));
  msg::Event e;
  REQUIRE(b.events(EventKind::Replanned, &e) >= 1);
  CHECK(e.arg >= 1);
  CHECK(b.count<msg::Obstacle>() >= 1);
  MESSAGE("closest the rover's centre came to the box: " << b.closest_to_box_mm << " mm");
  CHECK(b.closest_to_box_mm > 110.0f);   // half the rover's width is 75 mm: never touched
  CHECK(b.true_distance_to(300, 1600) < test::arrived_within_mm());
}

TEST_CASE("a path from the host replaces the rover's own detour") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;   // a host that heard every sweep and holds its path: it does not replan
  b.set_box(300, 1050, 200, 200);
  const core::Waypoint wps[] = {{300, 300}, {300, 1600}};
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.detour_left() > 0; }, 60000));
  CHECK((b.rover.flags() & StatusFlag::LocalReplan) != 0);
  const core::Waypoint around[] = {{300, 600}, {650, 800}, {650, 1300}, {300, 1600}};
  b.load_path(2, around, 4);
  CHECK(b.rover.detour_left() == 0);
  CHECK((b.rover.flags() & StatusFlag::LocalReplan) == 0);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 120000));
  CHECK(b.closest_to_box_mm > 110.0f);
}

TEST_CASE("with more echoes than disks the planner keeps those nearest the rover") {
  core::LocalPlanner lp;
  const core::Point rover{0, 0};
  for (int i = 0; i < core::LocalPlanner::kMaxEchoes; ++i) {
    lp.add(core::Point{static_cast<int16_t>(1000 + 100 * i), 0}, 200, rover);
  }
  CHECK(lp.inside(core::Point{1900, 150}));            // only the farthest echo's disk reaches here
  lp.add(core::Point{0, 300}, 200, rover);             // a near echo: the farthest gives way
  CHECK(lp.echoes() == core::LocalPlanner::kMaxEchoes);
  CHECK(lp.inside(core::Point{0, 300}));
  CHECK_FALSE(lp.inside(core::Point{1900, 150}));
  CHECK(lp.inside(core::Point{1700, 150}));            // the others stayed
  lp.add(core::Point{5000, 0}, 100, rover);            // farther than every one held: not kept
  CHECK_FALSE(lp.inside(core::Point{5000, 0}));
  // Nearness to the rover, not the disk's size: a wide disk near the rover stays over a narrow far one.
  lp.clear();
  for (int i = 0; i < core::LocalPlanner::kMaxEchoes; ++i) {
    lp.add(core::Point{static_cast<int16_t>(200 + 100 * i), 0}, i == 0 ? 400 : 150, rover);
  }
  lp.add(core::Point{0, 250}, 150, rover);
  CHECK(lp.inside(core::Point{200, -390}));            // the wide near disk is still held
  CHECK_FALSE(lp.inside(core::Point{1000, 140}));      // the farthest (at 1,000 mm) went
}

TEST_CASE("a sweep's start keeps what lies beside the front of the body, behind its sensor, and forgets the rest") {
  core::LocalPlanner lp;
  const core::Point then{0, 0}, now{0, 600};
  const int16_t north_x = 0, north_y = 256;   // the heading's unit vector times 256
  lp.add(core::Point{150, 650}, 60, then);    // beside the front half, behind the sensor (100 mm ahead)
  lp.add(core::Point{-200, 640}, 60, then);   // the same on the left
  lp.add(core::Point{120, 520}, 60, then);    // beside the rear half: backing out takes it nearer
  lp.add(core::Point{-100, 200}, 60, then);   // 400 mm behind it now
  lp.add(core::Point{0, 880}, 60, then);      // 280 mm ahead: the new sweep looks there afresh
  lp.keep_near(now, 350, north_x, north_y, 100);
  CHECK(lp.echoes() == 2);
  CHECK(lp.kept() == 2);
  CHECK(lp.inside(core::Point{150, 650}));
  CHECK(lp.inside(core::Point{-200, 640}));
  CHECK_FALSE(lp.inside(core::Point{120, 520}));
  CHECK_FALSE(lp.inside(core::Point{0, 880}));
  CHECK_FALSE(lp.inside(core::Point{-100, 200}));
  // Facing west instead, the echo at (-200, 640) lies 200 mm ahead: looked at afresh, forgotten;
  // the one at (150, 650) lies behind the centre.
  lp.keep_near(now, 350, -256, 0, 100);
  CHECK(lp.echoes() == 0);
}

TEST_CASE("kept echoes give way first, count for the turns with the corners' reach, and not for the leg") {
  core::LocalPlanner lp;
  const core::Point rover{0, 0};
  lp.add(core::Point{330, 50}, 180, rover);   // abeam, 50 mm ahead: kept at the next sweep's start
  lp.keep_near(rover, 350, 0, 256, 100);
  REQUIRE(lp.kept() == 1);
  // A kept one counts within the corners' reach of its point (its arc not added); without a
  // kept reach, as a fresh one does (its arc, 10 mm, and the reach). It lies 333.8 mm off.
  CHECK_FALSE(lp.within(rover, 170, 400, 140));
  CHECK_FALSE(lp.within(rover, 170, 400, 333));
  CHECK(lp.within(rover, 170, 400, 334));
  CHECK(lp.within(rover, 170, 324, 0));
  CHECK_FALSE(lp.within(rover, 170, 323, 0));
  // A leg through it: blocked by every echo, not by the fresh ones alone.
  CHECK(lp.blocks(rover, core::Point{800, 50}));
  CHECK_FALSE(lp.blocks(rover, core::Point{800, 50}, 0, true));
  // Fresh echoes fill the rest; when all are held, the kept one (the farthest) goes, and the
  // new echo counts as fresh.
  for (int i = 1; i < core::LocalPlanner::kMaxEchoes; ++i) {
    lp.add(core::Point{static_cast<int16_t>(-100 + 20 * i), 100}, 180, rover);
  }
  REQUIRE(lp.echoes() == core::LocalPlanner::kMaxEchoes);
  lp.add(core::Point{0, -100}, 180, rover);
  CHECK(lp.kept() == 0);
  CHECK_FALSE(lp.inside(core::Point{330, 50}));
  CHECK(lp.blocks(rover, core::Point{0, -800}, 0, true));
}

TEST_CASE("a disk the leg's start lies in blocks the leg only if the leg leads further in") {
  core::LocalPlanner lp;
  const core::Point rover{0, 0};
  lp.add(core::Point{0, -100}, 200, rover);   // just behind the rover, which is inside its disk
  CHECK_FALSE(lp.blocks(rover, core::Point{0, 800}));    // straight away from it
  CHECK_FALSE(lp.blocks(rover, core::Point{800, 0}));    // abeam of it: the nearest point is the start
  CHECK(lp.blocks(rover, core::Point{0, -800}));         // back through it
  CHECK(lp.blocks(rover, core::Point{800, -300}));       // past it, nearer than the start
  lp.clear();
  lp.add(core::Point{0, 300}, 200, rover);    // ahead, the start outside: as before
  CHECK(lp.blocks(rover, core::Point{0, 800}));
  CHECK_FALSE(lp.blocks(rover, core::Point{0, -800}));
}

// The host's word (HEARTBEAT's scan_heard and path_id): the rover takes its path past what the
// sonar saw only when the host heard that sweep whole and holds that path.
TEST_CASE("a host that did not hear the sweep: the rover holds and sweeps again, and takes the path on the host's word only once it heard") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;
  b.hears_sweeps = false;          // every sweep's reports lost on the radio
  b.set_box(300, 1050, 200, 200);  // on the leg; the host's path runs through it
  const core::Waypoint wps[] = {{300, 300}, {300, 1600}};
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.blocked(); }, 60000));
  const float y_blocked = b.plant.y_mm;
  const int sweeps = b.events(EventKind::ScanDone);
  bool planned = false, moved = false;
  b.run_until([&] {
    planned = planned || b.rover.planning_detour();
    moved = moved || fabsf(b.plant.y_mm - y_blocked) > 5.0f;
    return false;
  }, 12000);
  CHECK(b.events(EventKind::ScanDone) >= sweeps + 2);   // it said the sweep again, and again
  CHECK_FALSE(planned);   // no way round of its own while the radio is up: its sonar sees ahead only
  CHECK_FALSE(moved);
  // The host hears the next sweep: it keeps its path (it does not replan), so the rover goes on
  // on its word, its reflex stops it at the box, and it finds its own way round.
  b.hears_sweeps = true;
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 120000));
  CHECK(b.closest_to_box_mm > 110.0f);
  CHECK(b.true_distance_to(300, 1600) < test::arrived_within_mm());
}

TEST_CASE("a Blocked rover goes on at once along a new path that clears what the sweep saw") {
  Bench b;
  b.stream_fixes = true;
  b.heartbeats = true;
  b.hears_sweeps = false;
  b.set_box(300, 1050, 200, 200);
  const core::Waypoint wps[] = {{300, 300}, {300, 1600}};
  b.start_mission(wps, 2);
  REQUIRE(b.run_until([&] { return b.rover.blocked(); }, 60000));
  const core::Waypoint around[] = {{650, 800}, {650, 1300}, {300, 1600}};
  b.load_path(2, around, 3);
  REQUIRE(b.run_until([&] { return !b.rover.blocked(); }, 500));
  CHECK(b.rover.state() != RoverState::Scan);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Arrived; }, 120000));
  CHECK(b.closest_to_box_mm > 110.0f);
}
