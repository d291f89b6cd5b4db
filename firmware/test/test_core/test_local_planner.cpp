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
  lp.add(Point{300, 700}, 230);  // an echo 0.4 m ahead with its clearance and beam width
  lp.add(Point{340, 700}, 230);
  uint8_t scratch[LocalPlanner::kScratchBytes];
  Point out[LocalPlanner::kMaxDetour];
  const Point start{300, 300}, goal{300, 1000};
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
  for (int16_t i = 0; i < 9; ++i) lp.add(Point{static_cast<int16_t>(100 + 60 * i), static_cast<int16_t>(650 + (i % 2) * 60)}, 120);
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
  for (int16_t i = 0; i < 9; ++i) lp.add(Point{static_cast<int16_t>(-200 + 110 * i), 650}, 200);  // a wall
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

TEST_CASE("with more echoes than disks the planner keeps the nearest (the smallest disks)") {
  core::LocalPlanner lp;
  for (int i = 0; i < core::LocalPlanner::kMaxEchoes; ++i) {
    lp.add(core::Point{static_cast<int16_t>(1000 + 100 * i), 0}, static_cast<uint16_t>(300 + i));
  }
  CHECK(lp.inside(core::Point{1800, 305}));            // only the farthest disk (radius 308) reaches here
  lp.add(core::Point{0, 0}, 200);                      // a near echo: replaces the radius-308 disk
  CHECK(lp.echoes() == core::LocalPlanner::kMaxEchoes);
  CHECK(lp.inside(core::Point{0, 0}));
  CHECK_FALSE(lp.inside(core::Point{1800, 305}));      // ... and it gave way
  lp.add(core::Point{5000, 0}, 900);                   // far and wide: not kept
  CHECK_FALSE(lp.inside(core::Point{5000, 0}));
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
