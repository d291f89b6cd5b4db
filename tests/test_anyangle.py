"""Any-angle paths (issue 28): planner="theta" (Lazy Theta*, planning/theta.py) and the
visibility-graph optimum the benchmark measures it against (planning/visibility.py).

Theta*: every segment touches no inflated cell (checked by the project's segment check and by
fine sampling), it is never longer than A*'s optimum on the same grid, it is the straight line
when that is clear, and it fails with A*'s errors. The visibility optimum: a square between
start and goal, with the length worked out by hand.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from tests.planning_checks import SEED_SCENARIOS, sampled_cells_free, scenario_grid
from tests.test_planning_cli import run_cli

from rovernav.planning import (
    PLANNERS,
    GoalBlocked,
    OccupancyGrid,
    OutsideArena,
    PlannerConfig,
    StartBlocked,
    Unreachable,
    plan,
)
from rovernav.planning.theta import snap_to_corners, theta_points, tighten_points
from rovernav.planning.visibility import grid_optimum, inflated_polygons, scenario_optimum, shortest_path
from rovernav.scenario import load_scenario

EPS_M = 1e-9


def random_grid(seed: int, n: int = 60, boxes: int = 12) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    blocked = np.zeros((n, n), dtype=bool)
    for _ in range(boxes):
        x, y = rng.integers(0, n - 4, 2)
        w, h = rng.integers(1, 12, 2)
        blocked[y : y + h, x : x + w] = True
    return OccupancyGrid.from_layers(blocked, resolution_m=0.05)


def free_centres(grid: OccupancyGrid, seed: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """Two free cell centres [m] far apart (A*'s cost_m runs centre to centre)."""
    rng = np.random.default_rng(seed)
    free = np.argwhere(~grid.inflated)
    for _ in range(100):
        (ay, ax), (by, bx) = free[rng.integers(0, len(free), 2)]
        if abs(int(ax) - int(bx)) + abs(int(ay) - int(by)) > grid.nx // 2:
            return grid.cell_to_world(ax, ay), grid.cell_to_world(bx, by)
    raise AssertionError("no two free cells far apart")


# --- Theta* -----------------------------------------------------------------------------------


def test_theta_is_a_planner_of_plan_and_of_the_cli(capsys):
    assert "theta" in PLANNERS
    code, out, err = run_cli(["plan", "seed-small-obstacles", "--planner", "theta", "--json"], capsys)
    doc = json.loads(out)
    assert code == 0 and doc["found"] and doc["planner"] == "theta"
    assert doc["waypoints"][0] == [0.3, 0.3] and doc["waypoints"][-1] == [2.0, 1.4]


@pytest.mark.parametrize("name", SEED_SCENARIOS + ("full-echoes-posts", "full-echoes-wall"))
def test_theta_paths_on_the_shared_scenarios_are_clear_and_no_longer_than_astars(name):
    scenario, grid = scenario_grid(name)
    theta = plan(grid, scenario.start.xy, scenario.target.xy, planner="theta")
    astar = plan(grid, scenario.start.xy, scenario.target.xy, planner="astar")
    assert theta.waypoints[0] == scenario.start.xy and theta.waypoints[-1] == scenario.target.xy
    assert not grid.path_blocked(theta.waypoints)
    assert sampled_cells_free(grid.inflated, grid.resolution_m, theta.waypoints)
    assert theta.cost_m == pytest.approx(theta.length_m)
    # Both drive from the exact start to the exact target here.
    assert theta.length_m <= astar.length_m + EPS_M


@pytest.mark.parametrize("seed", range(12))
def test_theta_is_clear_and_never_longer_than_astars_optimum_on_random_grids(seed):
    grid = random_grid(seed)
    start, goal = free_centres(grid, seed)
    try:
        astar = plan(grid, start, goal, planner="astar")
    except Unreachable:
        with pytest.raises(Unreachable):
            plan(grid, start, goal, planner="theta")
        return
    theta = plan(grid, start, goal, planner="theta")
    assert not grid.path_blocked(theta.waypoints)
    assert sampled_cells_free(grid.inflated, grid.resolution_m, theta.waypoints)
    # From cell centre to cell centre, A*'s cost_m is its optimum on the 16-direction grid.
    assert theta.length_m <= astar.cost_m + EPS_M
    assert theta.length_m >= math.dist(start, goal) - EPS_M


def test_theta_is_the_straight_line_when_that_is_clear():
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    start, goal = (0.31, 0.42), (1.97, 1.33)
    assert grid.segment_clear(start, goal)
    result = plan(grid, start, goal, planner="theta")
    assert result.waypoints == (start, goal)
    assert result.length_m == pytest.approx(math.dist(start, goal), abs=1e-12)


def test_theta_within_one_cell_is_the_straight_line():
    grid = OccupancyGrid(2.0, 2.0, PlannerConfig())
    result = plan(grid, (1.001, 1.001), (1.02, 1.015), planner="theta")
    assert result.waypoints == ((1.001, 1.001), (1.02, 1.015))


def test_theta_raises_astars_errors():
    scenario, grid = scenario_grid("seed-large-obstacles")
    inside = (scenario.obstacles[0].x_m, scenario.obstacles[0].y_m)
    for planner in ("astar", "theta"):
        with pytest.raises(StartBlocked):
            plan(grid, inside, scenario.target.xy, planner=planner)
        with pytest.raises(GoalBlocked):
            plan(grid, scenario.start.xy, inside, planner=planner)
        with pytest.raises(OutsideArena):
            plan(grid, (-0.1, 0.5), scenario.target.xy, planner=planner)
    walled = OccupancyGrid(2.5, 2.5, PlannerConfig())
    walled.add_box(1.25, 0.9, 2.5, 0.1)  # a wall across the arena
    for planner in ("astar", "theta"):
        with pytest.raises(Unreachable):
            plan(walled, (0.5, 0.4), (2.0, 2.0), planner=planner)


def test_theta_kernel_compiled_and_plain_agree():
    grid = random_grid(3)
    start, goal = free_centres(grid, 3)
    ends = grid.to_cell_units([start, goal])
    args = (grid.inflated, ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1])
    fast, cost, expansions = theta_points(*args)
    slow, cost_py, expansions_py = theta_points.py_func(*args)
    assert np.array_equal(fast, slow) and cost == pytest.approx(cost_py) and expansions == expansions_py


def test_tightening_keeps_a_path_clear_and_never_lengthens_it():
    grid = random_grid(5)
    start, goal = free_centres(grid, 5)
    ends = grid.to_cell_units([start, goal])
    points, _, _ = theta_points(grid.inflated, ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1])
    tight = tighten_points(grid.inflated, points)

    def length(p):
        return float(np.hypot(*np.diff(p, axis=0).T).sum())

    assert length(tight) <= length(points) + 1e-12
    assert not grid.path_blocked(tight * grid.resolution_m)
    assert np.array_equal(tight[[0, -1]], points[[0, -1]])


# --- the visibility-graph optimum ---------------------------------------------------------------


def test_visibility_optimum_round_one_square_without_inflation():
    # A 1 m square centred at (2, 2); start and goal on its axis 1.5 m from the centre: over
    # the two top corners, 2·|(1, 0.5)| + 1 along the top side.
    polys = inflated_polygons([(2.0, 2.0, 1.0, 1.0)], [], [], 0.0)
    result = shortest_path(polys, (0.5, 2.0), (3.5, 2.0), 4.0, 4.0, 0.0)
    assert result.length_m == pytest.approx(2 * math.hypot(1.0, 0.5) + 1.0, abs=1e-12)
    assert result.waypoints == ((0.5, 2.0), (1.5, 2.5), (2.5, 2.5), (3.5, 2.0))


def test_visibility_optimum_round_one_inflated_square_matches_the_hand_computed_length():
    # Grown by r = 0.2 the square's corners are quarter circles of radius r about (1.5, 2.5)
    # and (2.5, 2.5). From the start (0.3, 2): the tangent to the first circle, the arc to the
    # top side, the top side (1 m), and the same mirrored to the goal.
    r = 0.2
    start, goal = (0.3, 2.0), (3.7, 2.0)
    to_centre = math.hypot(1.2, 0.5)
    tangent = math.sqrt(to_centre**2 - r**2)
    turn = math.atan2(0.5, 1.2) + math.asin(r / to_centre)  # the tangent's heading = the arc's angle
    exact = 2 * (tangent + r * turn) + 1.0
    assert exact == pytest.approx(3.78874, abs=1e-5)
    outer = shortest_path(inflated_polygons([(2, 2, 1, 1)], [], [], r), start, goal, 4.0, 4.0, r).length_m
    inner = shortest_path(inflated_polygons([(2, 2, 1, 1)], [], [], r, inscribed=True), start, goal, 4, 4, r).length_m
    # Circumscribed: never shorter, and longer by at most (r / cos(π/32) − r) per radian turned.
    assert exact <= outer <= exact + (r / math.cos(math.pi / 32) - r) * 2 * turn + 1e-12
    assert inner <= exact
    assert outer - inner < 2e-3


def test_visibility_optimum_keeps_off_the_arena_wall_and_may_be_unreachable():
    # A box against the top wall and one against the bottom leave a 0.2 m gap: shut for r = 0.2.
    polys = inflated_polygons([(2.0, 3.05, 0.5, 1.9), (2.0, 0.95, 0.5, 1.9)], [], [], 0.2)
    assert math.isinf(shortest_path(polys, (0.5, 2.0), (3.5, 2.0), 4.0, 4.0, 0.2).length_m)
    # A box from y = 1 to 3 in an arena 3.3 m high: over it the rover would pass 0.1 m from the
    # wall (it needs 0.2), so the path goes under, and stays 0.2 m off every wall.
    polys = inflated_polygons([(2.0, 2.0, 0.5, 2.0)], [], [], 0.2)
    result = shortest_path(polys, (0.5, 2.0), (3.5, 2.0), 4.0, 3.3, 0.2)
    assert math.isfinite(result.length_m) and min(y for _, y in result.waypoints) < 1.0
    assert all(0.2 - 1e-9 <= x <= 3.8 + 1e-9 and 0.2 - 1e-9 <= y <= 3.1 + 1e-9 for x, y in result.waypoints)
    high = shortest_path(polys, (0.5, 2.0), (3.5, 2.0), 4.0, 4.0, 0.2)
    assert high.length_m == pytest.approx(result.length_m)  # by symmetry, over or under


def test_theta_is_within_two_percent_of_the_optimum_on_the_seeds_large_obstacles():
    scenario = load_scenario("seed-large-obstacles")
    config = PlannerConfig()
    grid = OccupancyGrid.from_scenario(scenario, config, all_obstacles=True)
    optimum = scenario_optimum(scenario, config.inflation_m).length_m
    theta = plan(grid, scenario.start.xy, scenario.target.xy, planner="theta").length_m
    astar = plan(grid, scenario.start.xy, scenario.target.xy, planner="astar").length_m
    assert optimum * 0.99 < theta <= optimum * 1.02 and theta < astar


def test_grid_optimum_round_a_block_of_cells_and_theta_against_it():
    # Cells x 4-5, y 3-6 blocked on a 10 × 10 grid (the square [4, 6] × [3, 7]); from (2.5, 4.5)
    # to (7.5, 4.5) [cells] under it, by its bottom corners (4, 3) and (6, 3): 2·|(1.5, 1.5)| + 2
    # (over the top corners would be 2·|(1.5, 2.5)| + 2).
    blocked = np.zeros((10, 10), dtype=bool)
    blocked[3:7, 4:6] = True
    best = grid_optimum(blocked, (2.5, 4.5), (7.5, 4.5))
    assert best == pytest.approx(2 * math.hypot(1.5, 1.5) + 2.0, abs=1e-6)
    assert grid_optimum(np.zeros((5, 5), dtype=bool), (0.5, 0.5), (4.5, 3.5)) == pytest.approx(5.0)
    # No path that touches no blocked cell is shorter; Theta*'s is within 1 % on the shared scenarios.
    for name in SEED_SCENARIOS:
        scenario, grid = scenario_grid(name)
        ends = grid.to_cell_units([scenario.start.xy, scenario.target.xy])
        floor_m = grid_optimum(grid.inflated, ends[0], ends[1]) * grid.resolution_m
        theta = plan(grid, scenario.start.xy, scenario.target.xy, planner="theta").length_m
        assert floor_m - 1e-6 <= theta <= 1.002 * floor_m, name


def test_theta_round_a_block_of_cells_is_the_grid_optimum():
    blocked = np.zeros((10, 10), dtype=bool)
    blocked[3:7, 4:6] = True
    grid = OccupancyGrid.from_layers(blocked, resolution_m=0.1)
    result = plan(grid, (0.25, 0.45), (0.75, 0.45), planner="theta")
    assert result.length_m == pytest.approx(0.1 * grid_optimum(blocked, (2.5, 4.5), (7.5, 4.5)), abs=1e-6)
    assert len(result.waypoints) == 4 and not grid.path_blocked(result.waypoints)


@pytest.mark.parametrize("seed", range(6))
def test_snapping_to_corners_keeps_a_path_clear_and_never_lengthens_it(seed):
    grid = random_grid(seed)
    start, goal = free_centres(grid, seed)
    ends = grid.to_cell_units([start, goal])
    points, _, _ = theta_points(grid.inflated, ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1])
    if not len(points):
        return
    snapped = snap_to_corners(grid.inflated, points)

    def length(p):
        return float(np.hypot(*np.diff(p, axis=0).T).sum())

    assert length(snapped) <= length(points) + 1e-12
    assert not grid.path_blocked(snapped * grid.resolution_m)
    assert sampled_cells_free(grid.inflated, grid.resolution_m, snapped * grid.resolution_m)
