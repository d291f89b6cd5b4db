"""Plans on the shared scenarios: A* paths never cross an inflated cell and simplify to a few
clear waypoints; Table 4.2 (A* reaches the target in both environments, the potential field is
trapped by the large obstacles only, across a spread of gains); and the planning errors name
the start or target that is off the arena, blocked or unreachable. (Split from test_planning.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.planning_checks import SEED_SCENARIOS, sampled_cells_free, scenario_grid

from rovernav.planning import (
    GoalBlocked,
    LocalMinimum,
    NoPathError,
    OccupancyGrid,
    OutsideArena,
    PlannerConfig,
    StartBlocked,
    Unreachable,
    plan,
)
from rovernav.planning.potential import body_layer
from rovernav.planning.simplify import simplify_points

# --- plans on the shared scenarios ----------------------------------------------------------------


def random_free_points(grid: OccupancyGrid, blocked: np.ndarray, n: int, seed: int):
    rng = np.random.default_rng(seed)
    points = []
    while len(points) < n:
        x, y = rng.uniform(0, grid.width_m), rng.uniform(0, grid.height_m)
        ix, iy = grid.world_to_cell(x, y)
        if not blocked[iy, ix]:
            points.append((x, y))
    return points


@pytest.mark.parametrize("name", SEED_SCENARIOS)
def test_no_segment_of_an_astar_path_crosses_an_inflated_cell(name):
    scenario, grid = scenario_grid(name)
    ends = [(scenario.start.xy, scenario.target.xy)]
    points = random_free_points(grid, grid.inflated, 30, seed=len(name))
    ends += list(zip(points[::2], points[1::2]))
    found = 0
    for start, goal in ends:
        try:
            result = plan(grid, start, goal)
        except Unreachable:
            continue
        found += 1
        assert result.waypoints[0] == start and result.waypoints[-1] == goal
        assert sampled_cells_free(grid.inflated, grid.resolution_m, result.waypoints)
        assert not grid.path_blocked(result.waypoints)
        assert result.length_m >= math.dist(start, goal) - 1e-9
    assert found >= len(ends) // 2


def test_paths_stay_clear_on_a_20_m_arena_at_5_cm():
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(20.0, 20.0, PlannerConfig(resolution_m=0.05))
    for _ in range(40):
        grid.add_box(rng.uniform(1, 19), rng.uniform(1, 19), rng.uniform(0.2, 2.0), rng.uniform(0.2, 2.0))
    for start, goal in zip(*[iter(random_free_points(grid, grid.inflated, 8, seed=5))] * 2):
        result = plan(grid, start, goal)
        assert sampled_cells_free(grid.inflated, 0.05, result.waypoints)
        assert result.length_m <= result.cost_m + 2 * 0.05 * math.sqrt(2)


@pytest.mark.parametrize("name", SEED_SCENARIOS)
def test_simplification_keeps_the_path_clear_and_drops_waypoints(name):
    scenario, grid = scenario_grid(name)
    full = plan(grid, scenario.start.xy, scenario.target.xy, simplify=False)
    short = plan(grid, scenario.start.xy, scenario.target.xy)
    assert len(short.waypoints) < len(full.waypoints) / 4
    assert short.waypoints[0] == scenario.start.xy and short.waypoints[-1] == scenario.target.xy
    assert short.length_m <= full.length_m + 1e-9
    assert sampled_cells_free(grid.inflated, grid.resolution_m, short.waypoints)
    assert short.cost_m == full.cost_m


def test_simplification_of_a_straight_run_keeps_only_its_ends():
    blocked = np.zeros((5, 10), dtype=bool)
    line = np.array([[x + 0.5, 2.5] for x in range(10)])
    assert simplify_points(blocked, line).tolist() == [[0.5, 2.5], [9.5, 2.5]]
    blocked[3, 5] = True  # beside the line, not on it
    assert len(simplify_points(blocked, line)) == 2
    blocked[2, 5] = True
    dogleg = np.array([[0.5, 2.5], [4.5, 2.5], [5.5, 1.5], [6.5, 2.5], [9.5, 2.5]])
    kept = simplify_points(blocked, dogleg)
    assert kept[0].tolist() == [0.5, 2.5] and kept[-1].tolist() == [9.5, 2.5] and len(kept) >= 3


# --- Table 4.2 -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["seed-large-obstacles", "seed-small-obstacles"])
def test_table_4_2_astar_reaches_the_target_in_both_environments(name):
    scenario, grid = scenario_grid(name)
    result = plan(grid, scenario.start.xy, scenario.target.xy, planner="astar")
    assert result.waypoints[-1] == scenario.target.xy


# Gains across the region the defaults sit in, and starts moved a little: not one lucky setting.
GAINS = [(k, c0) for k in (0.04, 0.07, 0.1) for c0 in (0.03, 0.1, 0.2)]
NUDGES = [(0.0, 0.0), (0.03, 0.0), (0.0, 0.03), (-0.03, 0.0), (0.0, -0.03), (0.05, 0.05), (-0.05, -0.05)]


@pytest.mark.parametrize("gain, influence", GAINS)
def test_table_4_2_the_potential_field_is_trapped_by_large_obstacles_only(gain, influence):
    config = PlannerConfig(potential_repulsive_gain=gain, potential_influence_m=influence)
    large, large_grid = scenario_grid("seed-large-obstacles", config)
    small, small_grid = scenario_grid("seed-small-obstacles", config)
    for dx, dy in NUDGES:
        with pytest.raises(LocalMinimum, match=r"trapped in a local minimum at \(\d\.\d\d, \d\.\d\d\) m"):
            plan(large_grid, (large.start.x_m + dx, large.start.y_m + dy), large.target.xy, planner="potential")
        result = plan(small_grid, (small.start.x_m + dx, small.start.y_m + dy), small.target.xy, planner="potential")
        assert result.waypoints[-1] == small.target.xy
        assert sampled_cells_free(body_layer(small_grid), small_grid.resolution_m, result.waypoints)


def test_the_potential_fields_trap_is_inside_the_u():
    scenario, grid = scenario_grid("seed-large-obstacles")
    with pytest.raises(LocalMinimum) as info:
        plan(grid, scenario.start.xy, scenario.target.xy, planner="potential")
    x, y = info.value.xy
    assert 0.8 < x < 1.2 and 0.65 < y < 1.1  # between the arms, before the back wall
    assert info.value.partial[0] == grid.cell_to_world(*grid.world_to_cell(*scenario.start.xy))
    assert isinstance(info.value, NoPathError)


def test_the_potential_fields_path_keeps_the_robot_radius_but_not_the_sonar_margin():
    scenario, grid = scenario_grid("seed-small-obstacles")
    result = plan(grid, scenario.start.xy, scenario.target.xy, planner="potential")
    body = body_layer(grid)
    assert not body[result.cells[:, 1], result.cells[:, 0]].any()
    assert (body <= grid.inflated).all() and body.sum() < grid.inflated.sum()


# --- errors ---------------------------------------------------------------------------------------


def test_a_start_or_target_off_the_arena_is_named():
    _, grid = scenario_grid("out-and-back")
    with pytest.raises(OutsideArena, match=r"^target \(2\.40, 1\.10\) m is outside the 2\.36 × 1\.75 m arena$"):
        plan(grid, (0.3, 0.3), (2.40, 1.10))
    with pytest.raises(OutsideArena, match=r"^start \(-0\.10, 0\.30\) m is outside"):
        plan(grid, (-0.1, 0.3), (2.0, 1.4))
    with pytest.raises(OutsideArena, match="start"):
        plan(grid, (math.nan, 0.3), (2.0, 1.4), planner="potential")


def test_a_blocked_start_or_target_is_named():
    scenario, grid = scenario_grid("seed-large-obstacles")
    with pytest.raises(StartBlocked, match=r"^start \(1\.30, 0\.88\) m is blocked: it lies within 0\.17 m"):
        plan(grid, (1.30, 0.875), scenario.target.xy)
    with pytest.raises(GoalBlocked, match=r"^target \(0\.10, 0\.88\) m is blocked.*arena wall"):
        plan(grid, scenario.start.xy, (0.10, 0.875))
    with pytest.raises(StartBlocked, match=r"within 0\.12 m \(robot radius\)"):
        plan(grid, (1.30, 0.875), scenario.target.xy, planner="potential")


def test_an_enclosed_target_is_unreachable():
    grid = OccupancyGrid(3.0, 3.0)
    for x, y, w, h in [(2.0, 1.4, 1.0, 0.1), (2.0, 2.6, 1.0, 0.1), (1.45, 2.0, 0.1, 1.3), (2.55, 2.0, 0.1, 1.3)]:
        grid.add_box(x, y, w, h)
    with pytest.raises(Unreachable, match=r"^no path from start \(0\.50, 0\.50\) m to target \(2\.00, 2\.00\) m"):
        plan(grid, (0.5, 0.5), (2.0, 2.0))
    with pytest.raises(NoPathError):
        plan(grid, (0.5, 0.5), (2.0, 2.0), planner="potential")
    with pytest.raises(ValueError, match="unknown planner 'dstar'"):
        plan(grid, (0.5, 0.5), (2.0, 2.0), planner="dstar")
