"""Issue 30: a scenario names a fleet's starts and sites; overlapping starts and too many rovers
are refused in one line; a generated arena is given starts and sites for a fleet."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rovernav.evaluation.fleet_arenas import FleetPlacementError, fleet_scenario
from rovernav.planning import OccupancyGrid, PlannerConfig, plan
from rovernav.scenario import START_SPACING_M, ScenarioError, load_scenario, parse_scenario, scenario_toml
from rovernav.sim.world import World

BASE = """
version = 1
[arena]
width_m = 2.36
height_m = 1.75
[start]
x_m = 0.30
y_m = 0.30
[target]
x_m = 2.0
y_m = 1.4
"""


def test_the_fleet_scenario_names_four_starts_and_sites_and_survives_its_own_text():
    sc = load_scenario("fleet-out-and-back")
    assert len(sc.starts) == 4 and len(sc.sites) == 4
    again = parse_scenario(scenario_toml(sc), "<again>")
    assert again.starts == sc.starts and again.sites == sc.sites
    legs = sc.fleet_legs(3)
    assert legs[0] == ((0.30, 0.30), (2.00, 1.40))  # rover 1 is out-and-back's rover
    assert [a for a, _ in legs] == [p.xy for p in sc.starts[:3]]
    assert len({b for _, b in legs}) == 3  # a site each


def test_sites_are_shared_in_turn_when_fewer_than_rovers():
    sc = parse_scenario(BASE + "[[starts]]\nx_m = 0.7\ny_m = 0.3\n", "<two>")
    assert [b for _, b in sc.fleet_legs(2)] == [(2.0, 1.4), (2.0, 1.4)]


def test_more_rovers_than_starts_is_refused_in_one_line():
    sc = load_scenario("out-and-back")
    with pytest.raises(ScenarioError) as err:
        sc.fleet_legs(3)
    text = str(err.value)
    assert "\n" not in text and "3 rovers" in text and "1 start" in text


@pytest.mark.parametrize("gap_m", [0.0, 0.10, START_SPACING_M - 0.005])
def test_overlapping_starts_are_refused_in_one_line(gap_m):
    text = BASE + f"[[starts]]\nx_m = {0.30 + gap_m}\ny_m = 0.30\n"
    with pytest.raises(ScenarioError) as err:
        parse_scenario(text, "fleet.toml")
    msg = str(err.value)
    assert msg.startswith("fleet.toml: starts[0]") and "overlaps start" in msg and "\n" not in msg


def test_starts_a_body_apart_are_taken_and_a_start_on_a_box_is_not():
    sc = parse_scenario(BASE + f"[[starts]]\nx_m = {0.30 + START_SPACING_M + 0.001}\ny_m = 0.30\n", "<ok>")
    assert len(sc.starts) == 2
    boxed = BASE + "[[starts]]\nx_m = 1.0\ny_m = 1.0\n[[obstacles]]\nx_m = 1.0\ny_m = 1.0\nw_m = 0.2\nh_m = 0.2\n"
    with pytest.raises(ScenarioError, match=r"starts\[0\] \(1, 1\) m is inside obstacles\[0\]"):
        parse_scenario(boxed, "<boxed>")
    with pytest.raises(ScenarioError, match=r"sites\[0\].x_m = 9.0 is outside the arena"):
        parse_scenario(BASE + "[[sites]]\nx_m = 9.0\ny_m = 1.0\n", "<off>")


def test_a_generated_arena_gets_a_base_and_sites_for_three():
    sc = load_scenario("seed-large-obstacles")
    fleet = fleet_scenario(sc, 3)
    assert fleet.starts[0] == sc.start and fleet.sites[0] == sc.target
    grid = OccupancyGrid.from_scenario(fleet, PlannerConfig(), all_obstacles=True)
    world = World.from_scenario(fleet)
    for group in (fleet.starts, fleet.sites):
        points = [p.xy for p in group]
        for i, p in enumerate(points):
            assert grid.is_free(*p) and not world.collides(p[0], p[1], fleet.start.heading_deg)
            for q in points[:i]:
                assert math.dist(p, q) >= START_SPACING_M
    legs = fleet.fleet_legs(3)
    for a, b in legs:
        assert plan(grid, a, b).length_m > 0
    # Each rover's way passes the others standing at their berths, and at their sites, as the
    # traffic rules draw them (no berth or site in a pocket another rover shuts).
    from rovernav.fleet.traffic import PLAN_CLEAR_M

    for k, (a, b) in enumerate(legs):
        for end in (0, 1):
            g = grid.copy()
            others = [leg[end] for j, leg in enumerate(legs) if j != k]
            g.add_disks(np.asarray(others), PLAN_CLEAR_M - grid.config.inflation_m)
            assert plan(g, a, b).length_m > 0
    for p in fleet.starts[1:]:  # the added berths face the target
        want = math.degrees(math.atan2(sc.target.x_m - p.x_m, sc.target.y_m - p.y_m)) % 360
        assert abs((p.heading_deg - want + 180) % 360 - 180) < 0.1
    # It parses back as the same scenario (its starts apart, on the arena, off the boxes).
    assert parse_scenario(scenario_toml(fleet), "<fleet>").starts == fleet.starts


def test_no_room_for_a_fleet_is_said():
    tight = parse_scenario(
        BASE.replace("2.36", "0.7").replace("1.75", "0.7").replace("2.0", "0.5").replace("1.4", "0.5"), "<tight>"
    )
    with pytest.raises(FleetPlacementError, match="no room for 4 starts"):
        fleet_scenario(dataclasses.replace(tight, name="tight"), 4)
