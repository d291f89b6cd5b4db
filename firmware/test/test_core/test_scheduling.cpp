// One heavy job a step (Rover::step): a FIX, a sonar result and what follows, a slice of the
// detour planner, the choice of the nearest leg. What is put off is done later, never lost, and
// fixes arriving every step starve nothing.
#include <doctest.h>

#include "harness.h"

using namespace rovernav;
using rovernav::test::Bench;

namespace {
const core::Waypoint kNorth[] = {{300, 300}, {300, 1400}};

// Steps until the sweep at the start of the mission is over; returns its length in ms.
uint32_t first_sweep_ms(Bench& b) {
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 5000));
  const uint32_t started = b.now_ms;
  REQUIRE(b.run_until([&] { return b.rover.state() != RoverState::Scan; }, 10000));
  return b.now_ms - started;
}
}  // namespace

TEST_CASE("a FIX every step: every sweep reading still reported, the sweep barely slower, STATUS still sent") {
  Bench every, usual;
  every.stream_fixes = usual.stream_fixes = true;
  every.fix_period_ms = 10;   // a FIX in every step: each sonar result lands in a step that took one
  every.start_mission(kNorth, 2);
  usual.start_mission(kNorth, 2);
  every.forget_said();
  usual.forget_said();
  const uint32_t t_every = first_sweep_ms(every), t_usual = first_sweep_ms(usual);
  MESSAGE("sweep " << t_usual << " ms with a FIX every 33 ms, " << t_every << " ms with one every step");
  CHECK(every.count<msg::Obstacle>() == 13);   // one report per ping: none lost
  CHECK(usual.count<msg::Obstacle>() == 13);
  CHECK(t_every <= t_usual + 13 * 20);          // at most a step or two later per ping
  const int status_before = every.count<msg::Status>();
  every.run_ms(2000);
  CHECK(every.count<msg::Status>() - status_before >= 9);   // every 200 ms, give or take a step
}

TEST_CASE("two FIXes in one step: the second is dropped, the first taken as if alone") {
  Bench two, one;
  Bench* both[] = {&two, &one};
  for (Bench* b : both) {
    b->hello();
    b->fix_now();
    b->run_ms(50);
  }
  const float before = one.rover.estimator().x_mm();
  msg::Fix first = one.fix_msg(3), second = one.fix_msg(3);
  first.x_mm = static_cast<int16_t>(first.x_mm + 6);
  second.x_mm = static_cast<int16_t>(second.x_mm + 12);
  one.send(first);
  two.send(first);
  two.send(second);   // the same step's bytes: both frames complete in one step
  one.step();
  two.step();
  CHECK(two.rover.estimator().x_mm() == one.rover.estimator().x_mm());
  CHECK(two.rover.estimator().x_mm() > before + 1.0f);   // the first was taken
  CHECK(two.rover.rx_counters().frames_ok == one.rover.rx_counters().frames_ok + 1);   // the second arrived whole
}

TEST_CASE("a step that puts a job off keeps the next for it: no FIX is taken there") {
  Bench b;
  b.stream_fixes = true;
  b.fix_period_ms = 10;
  b.start_mission(kNorth, 2);
  REQUIRE(b.run_until([&] { return b.rover.state() == RoverState::Scan; }, 5000));
  int reserved = 0, fix_in_reserved = 0, fixes = 0;
  while (b.rover.state() == RoverState::Scan && b.now_ms < 20000) {
    b.step();
    const uint8_t w = b.rover.step_work();
    if (w & core::Rover::kWorkFix) ++fixes;
    if (w & core::Rover::kWorkReserved) {
      ++reserved;
      if (w & core::Rover::kWorkFix) ++fix_in_reserved;
    }
    const int heavy = ((w & core::Rover::kWorkFix) ? 1 : 0) + ((w & core::Rover::kWorkPlanned) ? 1 : 0) +
                      ((w & core::Rover::kWorkOther) ? 1 : 0);
    CHECK(heavy <= 1);
  }
  MESSAGE(fixes << " fixes taken, " << reserved << " reserved steps in the sweep");
  CHECK(reserved >= 13);   // each ping's result, held once
  CHECK(fix_in_reserved == 0);
  CHECK(fixes > 0);
}
