"""Issue 30's rovers as moving obstacles: the traffic rules' geometry (a rover's stretch ahead,
who is in its way, a rover drawn into another's planning map, an echo off another rover), and a
short fleet in the simulator: every rover on its own address and slot, no byte collided after
the boot, no contact, each rover's figures in the report."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from rovernav.fleet.traffic import CLEAR_M, Traffic, ahead, polyline_point_m, polylines_m, sample
from rovernav.link import messages_gen as mg
from rovernav.mapping import LearnedMap
from rovernav.mapping.sonar_map import SonarReading
from rovernav.planning import OccupancyGrid, PlannerConfig


def test_ahead_cuts_a_path_at_its_length_and_sample_walks_it():
    path = [(0.0, 0.0), (0.3, 0.0), (0.3, 0.4)]
    cut = ahead(path, 0.45)
    assert cut[:2] == [(0.0, 0.0), (0.3, 0.0)] and math.isclose(cut[-1][1], 0.15)
    pts = sample(path, 0.05)
    assert pts[0] == (0.0, 0.0) and pts[-1] == (0.3, 0.4)
    assert all(math.dist(a, b) <= 0.0601 for a, b in zip(pts, pts[1:])) and len(pts) >= 14
    assert math.isclose(polyline_point_m(path, (0.1, 0.2)), 0.2)
    assert math.isclose(polylines_m([(0.0, 1.0), (1.0, 1.0)], path), 0.6, abs_tol=1e-9)


class _Mission(SimpleNamespace):
    """What the traffic rules read of a mission."""

    done = False
    parked = False
    start_xy = None  # its berth and its site (None: not in the way of a spot aside)
    target_xy = None

    def rover_xy(self):
        return self.xy

    def rest_of_leg(self):
        return [self.xy, *self.rest]


def _traffic(*rovers):
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    shared = LearnedMap(grid)
    missions = [_Mission(xy=xy, rest=rest, moving_leg=bool(rest), map=shared) for xy, rest in rovers]
    return Traffic(missions), shared


def test_a_rover_heading_at_another_is_blocked_and_one_moving_away_from_a_neighbour_is_not():
    # Rover 1 drives east at rover 2, which stands 0.8 m ahead; rover 3 stands 0.32 m beside
    # rover 1's start (their berths) and rover 1 moves away from it.
    t, _ = _traffic(((0.5, 0.5), [(1.5, 0.5)]), ((1.3, 0.5), []), ((0.5, 0.18), []))
    assert t.blockers(0) == []  # its 0.45 m ahead ends 0.35 m from rover 2: past CLEAR_M
    t.missions[0].xy = (0.6, 0.5)
    assert t.blockers(0) == [1]
    assert 2 not in t.blockers(0)  # its neighbour at the berth is left behind, not approached


def test_of_two_rovers_whose_stretches_meet_the_later_in_the_order_waits():
    t, _ = _traffic(((0.5, 0.5), [(1.5, 0.5)]), ((0.9, 0.9), [(0.9, 0.1)]))
    assert t.blockers(1) == [0]  # rover 2's stretch crosses rover 1's: rover 2 waits
    assert t.blockers(0) == []  # rover 1 goes first


def test_standing_rovers_are_drawn_into_a_planners_map_and_moving_ones_as_their_lanes():
    t, shared = _traffic(((0.5, 0.5), [(1.5, 0.5)]), ((1.2, 1.2), []), ((2.0, 0.3), [(2.0, 1.4)]))
    grid = t.planning_map(0).grid
    assert not grid.is_free(1.2, 1.2)  # the standing rover 2's body
    assert not grid.is_free(2.0, 0.9)  # rover 3's lane
    assert grid.is_free(0.5, 0.5)  # rover 1 itself is not drawn in
    assert shared.grid.is_free(1.2, 1.2)  # the shared map itself is left as it was
    assert t.planning_map(1).grid.is_free(1.2, 1.2) and not t.planning_map(1).grid.is_free(0.5, 0.5)


def test_an_echo_off_another_rovers_body_is_that_rover():
    t, shared = _traffic(((0.5, 0.5), [(1.5, 0.5)]), ((1.0, 0.5), []))
    offset = shared.grid.config.sonar_offset_m
    at_rover = SonarReading(0.5, 0.5, 90.0, 0.0, 0.5 - offset - 0.07, 0.6, 0.003)
    beside = SonarReading(0.5, 0.5, 0.0, 0.0, 0.4, 0.6, 0.003)  # straight up, nowhere near rover 2
    assert t.echo_is_rover(0, at_rover) and not t.echo_is_rover(0, beside)


class _ParkedMission(_Mission):
    """A mission parked at home (its trips done) or on a leg, that plans in straight lines."""

    planning_map = None

    def plan_from(self, start, goal, verdict=True, round_rovers=False):
        grid = self.planning_map().grid
        return [start, goal] if grid.is_free(*goal) and grid.segment_clear(start, goal) else None


def test_a_rover_parked_at_home_in_anothers_way_is_sent_aside_off_it_and_back_once_it_is_clear():
    # Rover 2, home from its trips, stands on rover 1's way to its berth beyond (a pocket with no
    # way round): it is sent to a spot clear of rover 1's way and of rover 3, by a way clear of
    # every rover; and it goes home only once no rover's way passes its berth.
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    shared = LearnedMap(grid)
    home = (0.7, 0.3)
    m1 = _ParkedMission(xy=(0.5, 1.0), rest=[(0.85, 0.45), (1.1, 0.3)], moving_leg=False, map=shared)
    m2 = _ParkedMission(xy=home, rest=[], moving_leg=False, map=shared, parked=True, done=False)
    m2.current_leg = SimpleNamespace(goal=home)
    m3 = _ParkedMission(xy=(0.3, 0.3), rest=[], moving_leg=False, map=shared)
    t = Traffic([m1, m2, m3])
    way = t._aside_spot(1, 0)
    assert way is not None and way[0] == home
    spot = way[-1]
    assert polyline_point_m(m1.rest_of_leg(), spot) >= CLEAR_M  # off rover 1's way
    assert math.dist(spot, m3.xy) >= CLEAR_M and math.dist(spot, m1.xy) >= CLEAR_M
    assert t.blockers(1, way) == []  # and the way there passes no rover
    m2.xy = spot
    m1.done, m1.parked = False, False
    m3.done, m3.parked = True, True
    assert t._wanted_home(1)  # rover 1's way still passes rover 2's berth
    m1.xy, m1.rest = (1.1, 0.3), []
    assert not t._wanted_home(1)  # rover 1 is home: rover 2 may go back


def test_a_rover_waiting_aside_in_the_way_of_a_rover_with_no_way_round_is_sent_aside_again():
    # Rover 3, its trips done, was sent aside from its berth for rover 1, to a spot 0.18 m from
    # rover 2's berth, and waits there (for rover 2's way to clear its own berth). Rover 2, held on
    # its way home, has no way round it: rover 3 is sent on to a spot off rover 2's way, as a rover
    # parked at its berth would be (before, only one at its berth was, and the two waited for good).
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    shared = LearnedMap(grid)
    sent = []
    m1 = _ParkedMission(xy=(0.3, 0.3), rest=[], moving_leg=False, map=shared, parked=True, parked_waiting=True)
    m2 = _ParkedMission(xy=(0.47, 1.15), rest=[(0.7, 0.3)], moving_leg=False, map=shared, parked_waiting=False)
    m3 = _ParkedMission(xy=(0.7, 0.48), rest=[], moving_leg=False, map=shared, parked=True, parked_waiting=True)
    m3.let_go = lambda now_s, path=None, aside=False: sent.append((path, aside))
    t = Traffic([m1, m2, m3])
    assert t.blockers(1) == [2]
    assert t._make_way(1, [2], 10.0)
    ((way, aside),) = sent
    assert aside and way[0] == m3.xy
    assert polyline_point_m(m2.rest_of_leg(), way[-1]) >= CLEAR_M  # off rover 2's way home
    assert t.make_ways == 1
    m3.parked_waiting = False  # on its way there: not sent anywhere else
    assert not t._make_way(1, [2], 11.0) and len(sent) == 1


def test_a_rover_parked_in_a_corridor_that_is_anothers_only_way_is_sent_beyond_the_near_rings():
    # A corridor along the bottom wall (a box over the rest of the arena): rover 1 drives east
    # along it to (1.45, 0.3), past rover 2, parked at (0.75, 0.3). Every spot within 0.9 m of
    # rover 2 is in the box's margin or on rover 1's way: its spot aside is further along, ahead.
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    grid.add_box(1.18, 1.2, 2.36, 1.1)
    shared = LearnedMap(grid)
    m1 = _ParkedMission(xy=(0.3, 0.3), rest=[(1.45, 0.3)], moving_leg=False, map=shared)
    m2 = _ParkedMission(xy=(0.75, 0.3), rest=[], moving_leg=False, map=shared, parked=True)
    t = Traffic([m1, m2])
    way = t._aside_spot(1, 0)
    assert way is not None and way[0] == (0.75, 0.3)
    spot = way[-1]
    assert math.dist(spot, m2.xy) > 0.9 and polyline_point_m(m1.rest_of_leg(), spot) >= CLEAR_M
    assert t.blockers(1, way) == []


def test_three_rovers_that_hold_each_other_round_are_a_ring_and_the_latest_gives_way_to_the_one_it_holds():
    # Rover 1 drives at rover 2, rover 2 at rover 3, rover 3 at rover 1: all three held.
    t, _ = _traffic(
        ((0.5, 0.5), [(1.1, 0.5)]),
        ((1.1, 0.5), [(0.8, 1.02)]),
        ((0.8, 1.02), [(0.5, 0.5)]),
    )
    for m in t.missions:
        m.held, m.moving_leg = True, False
    assert [t.blockers(k) for k in range(3)] == [[1], [2], [0]]
    assert t._cycle(2) == [2, 0, 1]  # rover 3 <- rover 1 <- rover 2 <- rover 3: rover 3 holds rover 2
    assert t._cycle(0) == [0, 1, 2]
    t.missions[1].held = False  # rover 2 on the move again: no ring
    assert t._cycle(2) is None


def test_clear_m_keeps_two_bodies_apart_at_any_heading():
    # Two rovers' rectangles (0.21 x 0.15 m) cannot touch when their centres are CLEAR_M apart.
    assert CLEAR_M > math.hypot(0.21, 0.15)


@pytest.mark.slow
def test_a_short_fleet_run_keeps_every_rover_on_its_own_address_and_slot(tmp_path):
    from rovernav.scenario import load_scenario
    from rovernav.sim.fleet_runner import FleetOptions, FleetSimulation

    log = tmp_path / "run.mcap"
    sim = FleetSimulation(
        load_scenario("fleet-out-and-back"), FleetOptions(rovers=3, trips=1, max_time_s=20.0, log=log)
    )
    sim.run()
    report = sim.report()
    sim.close_log(report)
    # The run log: the camera and the arena once, each rover's channels under /roverK.
    from mcap.reader import make_reader

    with open(log, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.id: c.topic for c in summary.channels.values()}
    counts = {topics[c]: n for c, n in summary.statistics.channel_message_counts.items()}
    assert counts["/camera/image"] > 0 and counts["/arena"] == 1
    for k in (1, 2, 3):
        assert counts[f"/rover{k}/link/rover_to_host"] > 20 and counts[f"/rover{k}/sim/true_pose"] > 100
        assert counts[f"/rover{k}/camera/fix"] > 100
    assert not any(t.startswith(("/link/", "/rover/")) for t in counts)  # no channel is nobody's
    from rovernav.runlog.replay import LogFileError, read_log

    with pytest.raises(LogFileError, match="a fleet's run log"):
        read_log(log)
    assert report["contacts"] == 0 and report["rovers"] == 3
    for k, rover in enumerate(report["per_rover"]):
        assert rover["rover"] == k + 1
        assert rover["link"]["slots"] > 50  # about 4 a second each
        assert rover["link"]["from_rover_frames"] > 20
        assert sim.host.missions[k].legs, "every rover was configured and started its first leg"
        assert sim.host.links[k].counters.dropped == 0  # no damaged frame reached any rover's link
        # Its time by what it did: every step counted once, held as the host's own count says.
        spent = rover["time_s"]
        assert sum(spent.values()) == pytest.approx(report["mission_time_s"], abs=0.05 * len(spent))
        m = sim.host.missions[k]
        held_s = rover["held"]["seconds"] + (m.held_for_s(sim.t) if m.held else 0.0)  # a hold not yet over too
        assert spent.get("held", 0.0) == pytest.approx(held_s, abs=0.15)
        assert set(spent) <= {"held", "parked", "over"} | {s.name.lower() for s in mg.RoverState}
        assert spent.get("scan", 0.0) > 0.5  # each began with a sweep (sweep_at_start)
    # The rovers speak only when polled: after the boot (all three at once) no byte collided.
    collided = sum(r.to_host.lost_by["collision"] for r in sim.rovers)
    boot_bytes = sum(r.to_host.frames.get("hello", [0])[0] for r in sim.rovers) * 64
    assert collided <= boot_bytes
    assert sim.radio.unroutable <= 3


def test_rovernav_sim_refuses_more_rovers_than_starts_in_one_line():
    out = subprocess.run(
        [
            str(Path(sys.executable).parent / "rovernav"),
            "sim",
            "out-and-back",
            "--rovers",
            "3",
            "--no-video",
            "--out",
            "/tmp/x",
        ],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "3 rovers but the scenario names 1 start" in out.stderr


def test_a_spot_aside_is_never_on_the_berth_or_site_of_a_rover_with_trips_to_do():
    # Rover 2 parked at home in rover 1's way; rover 3's berth lies where the nearest spot aside
    # would be: rover 2 is sent elsewhere (a rover aside on another's berth held it for good).
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    shared = LearnedMap(grid)
    home = (0.7, 0.3)
    m1 = _ParkedMission(xy=(0.5, 1.0), rest=[(0.85, 0.45), (1.1, 0.3)], moving_leg=False, map=shared)
    m2 = _ParkedMission(xy=home, rest=[], moving_leg=False, map=shared, parked=True)
    m2.current_leg = SimpleNamespace(goal=home)
    m3 = _ParkedMission(xy=(1.9, 1.5), rest=[], moving_leg=False, map=shared)
    t = Traffic([m1, m2, m3])
    free = t._aside_spot(1, 0)[-1]
    m3.start_xy = free  # rover 3's berth where rover 2 would have gone
    assert t._aside_spot(1, 0)[-1] == free  # the rule is the turn-care trial's (off by default)
    t.berth_rule = True
    again = t._aside_spot(1, 0)[-1]
    assert math.dist(again, free) >= 0.33
    m3.done = True  # a rover with its trips done is no one's concern
    assert t._aside_spot(1, 0)[-1] == free


def test_a_rover_that_gave_way_waits_until_the_other_has_passed_or_long_enough():
    from rovernav.fleet.traffic import GAVE_WAY_WAIT_S

    # Rover 2 gave way to rover 1 and waits aside at (1.0, 0.8); its way back runs down to (1.0,
    # 0.3), across rover 1's way along y = 0.4.
    t, _ = _traffic(((0.3, 0.4), [(1.8, 0.4)]), ((1.0, 0.8), [(1.0, 0.3)]))
    t._gave_way[1] = (0, 10.0)
    assert t._waits_for_passing(1, 11.0)  # rover 1 has yet to pass
    t.missions[0].xy = (1.5, 0.4)  # past: its way on no longer comes near rover 2's stretch
    assert not t._waits_for_passing(1, 12.0) and 1 not in t._gave_way
    t._gave_way[1] = (0, 10.0)
    t.missions[0].xy = (0.3, 0.4)
    assert not t._waits_for_passing(1, 10.0 + GAVE_WAY_WAIT_S)  # waited long enough: it goes
    t._gave_way[1] = (0, 10.0)
    t.missions[0].moving_leg = False  # rover 1 held (for rover 2, or any other): not waited for ...
    assert not t._waits_for_passing(1, 11.0)
    t.missions[0].moving_leg = True  # ... until it moves on
    assert t._waits_for_passing(1, 11.5)
    t.missions[0].done = True  # done (or home): nothing to wait for
    assert not t._waits_for_passing(1, 12.0) and 1 not in t._gave_way


def test_a_held_rover_waits_while_it_settles_or_waits_for_the_rover_it_gave_way_to():
    # Rover 2, held, its stretch clear: let go after CLEAR_FOR_S, unless it settles after a refused
    # turn, or waits for rover 1 to pass.
    from rovernav.fleet.traffic import CLEAR_FOR_S

    t, _ = _traffic(((0.3, 0.4), [(1.8, 0.4)]), ((1.0, 1.2), [(1.0, 1.6)]))
    m2 = t.missions[1]
    let_go = []
    m2.held, m2.done, m2.parked, m2.parked_at_rest = True, False, False, False
    m2.let_go = lambda now_s, path=None, aside=False: let_go.append(now_s)
    m2.settling = lambda now_s: now_s < 5.0
    t.missions[0].settling = lambda now_s: False
    for now in (1.0, 1.0 + CLEAR_FOR_S, 4.9):
        assert not t._try_let_go(1, now)
    assert not t._try_let_go(1, 5.0) and t._try_let_go(1, 5.0 + CLEAR_FOR_S) and let_go == [5.0 + CLEAR_FOR_S]
    m2.xy, m2.rest = (1.0, 0.8), [(1.0, 0.2)]  # now its way crosses rover 1's: it waits for it
    t._gave_way[1] = (0, 10.0)
    t._clear_since.clear()
    t.missions[0].xy = (0.2, 0.4)
    assert not t._try_let_go(1, 11.0) and not t._try_let_go(1, 11.0 + CLEAR_FOR_S)
    del t._gave_way[1]  # the same, not having given way: let go
    assert not t._try_let_go(1, 12.0) and t._try_let_go(1, 12.0 + CLEAR_FOR_S)


def test_a_stuck_fleets_message_says_where_each_rover_stands_and_what_holds_it():
    from rovernav.scenario import load_scenario
    from rovernav.sim.fleet_runner import FleetOptions, FleetSimulation

    sim = FleetSimulation(load_scenario("fleet-out-and-back"), FleetOptions(rovers=3, trips=1, max_time_s=7.0))
    assert sim._standing(0, 0.0) == "rover 1 not heard at (0.30, 0.30) m"
    said = {}
    tick = sim.host.tick

    def tick_and_look(now_s):
        tick(now_s)
        if now_s >= 4.0 and not said:  # (the traffic rules let it go at their next tick)
            sim.host.missions[1].hold(now_s, "rover 1 is in the way (at (0.30, 0.30) m)")
            said.update({k: sim._standing(k, now_s + 2.0) for k in range(3)})

    sim.host.tick = tick_and_look
    sim.run()
    assert re.fullmatch(r"rover 2 \w+ at \(0\.7\d, 0\.3\d\) m, held 2 s \(.*\)", said[1]), said[1]
    assert said[1].endswith(", held 2 s (rover 1 is in the way (at (0.30, 0.30) m))")
    assert said[0].endswith(", on leg 1")  # greeted and on its way
    assert sim._standing(0, 7.0).endswith(", its mission over")  # the time limit ended it
