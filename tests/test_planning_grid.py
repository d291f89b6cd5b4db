"""The occupancy grid: world and cell coordinates, obstacles inflated by the robot radius plus
the sonar margin (boxes, oblique walls and posts, each by its exact distance, incrementally as
from scratch; boxes compiled exactly as numpy), the planner's configuration, and a scenario's known and unknown obstacles.
(Split from test_planning.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.planning_checks import sampled_cells_free, scenario_grid

from rovernav.planning import OccupancyGrid, PlannerConfig, plan

# --- the occupancy grid -------------------------------------------------------------------------


def test_world_and_cell_coordinates_meet_at_cell_centres():
    grid = OccupancyGrid(2.36, 1.75)
    assert (grid.nx, grid.ny) == (79, 59)
    assert grid.world_to_cell(0.0, 0.0) == (0, 0)
    assert grid.world_to_cell(0.031, 0.059) == (1, 1)
    assert grid.world_to_cell(2.36, 1.75) == (78, 58)
    assert grid.cell_to_world(10, 20) == pytest.approx((0.315, 0.615))
    assert grid.world_to_cell(*grid.cell_to_world(33, 44)) == (33, 44)


def test_obstacles_are_inflated_by_the_robot_radius_plus_the_sonar_margin():
    grid = OccupancyGrid(2.0, 2.0)
    grid.add_box(1.0, 1.0, 0.2, 0.2)
    margin = 0.12 + 0.05
    for (x, y), blocked in [
        ((1.0, 1.0), True),
        ((1.1 + margin - 0.02, 1.0), True),
        ((1.1 + margin + 0.02, 1.0), False),
        ((1.0, 0.9 - margin + 0.02), True),
        ((1.0, 0.9 - margin - 0.02), False),
        # past the corner the margin is round: 0.12 m out on both axes is 0.17 m away
        ((1.1 + 0.11, 1.1 + 0.11), True),
        ((1.1 + 0.13, 1.1 + 0.13), False),
    ]:
        assert grid.is_free(x, y) is not blocked, (x, y)
    assert grid.raw[grid.world_to_cell(1.0, 1.0)[::-1]] and not grid.raw[grid.world_to_cell(1.15, 1.0)[::-1]]
    # The arena's border is a wall, inflated alike.
    assert not grid.is_free(0.16, 1.0) and grid.is_free(0.19, 1.0)
    assert not grid.is_free(1.0, 2.0 - 0.16) and grid.is_free(1.0, 2.0 - 0.19)


def test_every_cell_within_the_margin_of_an_obstacle_is_inflated():
    scenario, grid = scenario_grid("seed-small-obstacles")
    px = grid.xs[None, :]
    py = grid.ys[:, None]
    for o in scenario.obstacles:
        d = np.hypot(np.maximum(abs(px - o.x_m) - o.w_m / 2, 0), np.maximum(abs(py - o.y_m) - o.h_m / 2, 0))
        assert grid.inflated[d <= 0.17].all()


def test_planner_config_refuses_unknown_keys_and_bad_values():
    assert PlannerConfig.from_dict({"resolution_m": 0.05}).resolution_m == 0.05
    assert PlannerConfig().inflation_m == pytest.approx(0.17)
    with pytest.raises(ValueError, match="unknown key 'robot_radius'"):
        PlannerConfig.from_dict({"robot_radius": 0.1})
    with pytest.raises(ValueError, match="resolution_m must be > 0"):
        PlannerConfig.from_dict({"resolution_m": 0})
    with pytest.raises(ValueError, match="sonar_margin_m must be ≥ 0"):
        PlannerConfig.from_dict({"sonar_margin_m": -0.01})
    with pytest.raises(ValueError, match="robot_radius_m must be a finite number"):
        PlannerConfig.from_dict({"robot_radius_m": "wide"})


def test_incremental_inflation_equals_inflating_from_scratch():
    rng = np.random.default_rng(11)
    grid = OccupancyGrid(3.0, 2.0)
    for _ in range(5):
        grid.add_box(rng.uniform(0, 3), rng.uniform(0, 2), rng.uniform(0.05, 0.5), rng.uniform(0.05, 0.5))
        grid.add_disks(
            rng.uniform((0.3, 0.3), (2.7, 1.7), size=(int(rng.integers(1, 30)), 2)), rng.uniform(0.005, 0.03)
        )
    assert (grid.inflated == grid.blocked_within(grid.config.inflation_m)).all()
    new, newly = grid.add_disks(np.array([[-0.1, -0.2], [3.5, 1.0]]), 0.02)  # off the arena: dropped
    assert len(new) == 0 and newly == 0


def test_compiled_box_inflation_blocks_exactly_the_cells_of_numpys_distances():
    """add_box inflates with a compiled loop (issue 29); it must block the very cells the numpy
    distances (`_box_distance`, then `_grow`) did, the borderline ones included, with the same
    counts: boxes on cell edges and centres, and inflations that are whole numbers of cells."""
    rng = np.random.default_rng(29)
    for res, radius, margin in (
        (0.03, 0.12, 0.05),
        (0.05, 0.12, 0.05),
        (0.05, 0.1, 0.05),
        (0.02, 0.1, 0.0),
        (0.1, 0.3, 0.0),
    ):
        config = PlannerConfig(resolution_m=res, robot_radius_m=radius, sonar_margin_m=margin)
        grid = OccupancyGrid(4.0, 3.0, config)
        numpy_grid = OccupancyGrid(4.0, 3.0, config)
        for i in range(120):
            if i % 3 == 0:  # edges on cell edges or centres: distances land on the limit exactly
                x, y = rng.integers(-5, 85, 2) * res / 2
                w, h = rng.integers(1, 30, 2) * res / 2
            else:
                x, y = rng.uniform(-0.3, 4.3), rng.uniform(-0.3, 3.3)
                w, h = rng.uniform(0.01, 1.0, 2)
            newly = grid.add_box(x, y, w, h)
            expected = numpy_grid._grow(
                numpy_grid._box_distance((float(x), float(y), float(w), float(h)), config.inflation_m)
            )
            assert newly == expected
            assert (grid.inflated == numpy_grid.inflated).all()
        assert (grid.inflated == grid.blocked_within(config.inflation_m)).all()


def test_the_wall_band_is_the_cells_within_the_radius_of_the_wall():
    for width_m, height_m, res in ((2.36, 1.75, 0.03), (3.0, 2.0, 0.05), (20.0, 20.0, 0.05), (0.5, 7.0, 0.1)):
        grid = OccupancyGrid(width_m, height_m, PlannerConfig(resolution_m=res))
        for radius_m in (0.0, res / 2, res, 0.17, 2.5 * res, 3 * res, 1.0):
            assert (grid.wall_band(radius_m) == (grid.wall_distance() <= radius_m + 1e-12)).all()


# --- walls and posts ----------------------------------------------------------------------------


def _rect_outline(corners, step_m=0.0005):
    """Points every step_m along a polygon's outline."""
    pts = []
    for a, b in zip(corners, corners[1:] + corners[:1]):
        n = max(2, int(math.dist(a, b) / step_m) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(np.asarray(a) + (np.asarray(b) - np.asarray(a)) * t)
    return np.concatenate(pts)


def _inside_convex(px, py, corners):
    """Whether points lie inside (or on) a convex polygon given counter-clockwise or clockwise."""
    signs = []
    for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
        signs.append((bx - ax) * (py - ay) - (by - ay) * (px - ax))
    signs = np.stack(signs)
    return np.all(signs >= -1e-12, axis=0) | np.all(signs <= 1e-12, axis=0)


def _brute_distance(grid, outline, inside):
    """Distance from every cell centre to a shape: to the nearest outline point, 0 inside."""
    cx, cy = np.meshgrid(grid.xs, grid.ys)
    d = np.full(cx.shape, np.inf)
    for chunk in np.array_split(outline, max(1, len(outline) // 500)):
        d = np.minimum(d, np.hypot(cx[..., None] - chunk[:, 0], cy[..., None] - chunk[:, 1]).min(axis=2))
    return np.where(inside(cx, cy), 0.0, d)


def test_an_oblique_wall_is_inflated_by_its_exact_distance():
    from rovernav.scenario import Wall

    grid = OccupancyGrid(2.0, 1.6)
    wall = Wall(0.45, 0.35, 1.4, 1.1, 0.07)
    grid.add_wall(wall.x0_m, wall.y0_m, wall.x1_m, wall.y1_m, wall.thickness_m)
    corners = list(wall.corners())
    bf = _brute_distance(grid, _rect_outline(corners), lambda x, y: _inside_convex(x, y, corners))
    inflation = grid.config.inflation_m
    wall_band = grid.wall_band(inflation)
    sure = np.abs(bf - inflation) > 1e-3  # the sampled outline is within 0.25 mm of the true one
    assert ((grid.inflated == ((bf <= inflation) | wall_band)) | ~sure).all()
    assert (sure & ~wall_band).sum() > 500  # the comparison covers many cells
    # beside the wall's sides: the distance to the centre line minus half the thickness
    ix, iy = grid.world_to_cell(0.8, 0.9)
    px, py = grid.cell_to_world(ix, iy)
    ex, ey = wall.x1_m - wall.x0_m, wall.y1_m - wall.y0_m
    t = ((px - wall.x0_m) * ex + (py - wall.y0_m) * ey) / (ex * ex + ey * ey)
    assert 0.0 < t < 1.0
    to_line = math.hypot(px - wall.x0_m - t * ex, py - wall.y0_m - t * ey)
    assert grid.obstacle_distance(0.5)[iy, ix] == pytest.approx(to_line - wall.thickness_m / 2, abs=1e-12)
    # raw: every cell the rectangle covers some of, and no cell it cannot reach
    half = grid.resolution_m / 2
    samples = np.linspace(-half + 1e-4, half - 1e-4, 9)
    cx, cy = np.meshgrid(grid.xs, grid.ys)
    covered = np.zeros_like(grid.raw)
    for sx in samples:
        for sy in samples:
            covered |= _inside_convex(cx + sx, cy + sy, corners)
    assert (grid.raw >= covered).all() and covered.sum() > 50
    assert (bf[grid.raw] <= half * math.sqrt(2) + 1e-9).all()
    assert (grid.inflated == grid.blocked_within(inflation)).all()


def test_a_post_is_inflated_by_its_exact_distance_and_covers_its_cells():
    grid = OccupancyGrid(1.5, 1.2)
    x, y, r = 0.71, 0.52, 0.063
    grid.add_post(x, y, r)
    cx, cy = np.meshgrid(grid.xs, grid.ys)
    angles = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    outline = np.stack([x + r * np.cos(angles), y + r * np.sin(angles)], axis=1)
    bf = _brute_distance(grid, outline, lambda px, py: np.hypot(px - x, py - y) <= r)
    inflation = grid.config.inflation_m
    sure = np.abs(bf - inflation) > 1e-3
    assert ((grid.inflated == ((bf <= inflation) | grid.wall_band(inflation))) | ~sure).all()
    half = grid.resolution_m / 2
    covered = np.zeros_like(grid.raw)
    for sx in np.linspace(-half + 1e-4, half - 1e-4, 9):
        for sy in np.linspace(-half + 1e-4, half - 1e-4, 9):
            covered |= np.hypot(cx + sx - x, cy + sy - y) < r
    assert (grid.raw >= covered).all() and (bf[grid.raw] <= half * math.sqrt(2) + 1e-9).all()
    assert (grid.inflated == grid.blocked_within(inflation)).all()
    with pytest.raises(ValueError, match="radius"):
        grid.add_post(0.5, 0.5, 0.0)
    with pytest.raises(ValueError, match="length"):
        grid.add_wall(0.5, 0.5, 0.5, 0.5, 0.05)
    with pytest.raises(ValueError, match="thickness"):
        grid.add_wall(0.5, 0.5, 0.9, 0.5, -0.05)


def test_a_wall_along_an_axis_is_the_box_it_covers():
    as_wall, as_box = OccupancyGrid(2.0, 1.5), OccupancyGrid(2.0, 1.5)
    as_wall.add_wall(1.0, 0.0, 1.0, 0.9, 0.05)
    as_wall.add_wall(0.2, 1.2, 0.8, 1.2, 0.04)
    as_box.add_box(1.0, 0.45, 0.05, 0.9)
    as_box.add_box(0.5, 1.2, 0.6, 0.04)
    assert (as_wall.raw == as_box.raw).all() and (as_wall.inflated == as_box.inflated).all()


def test_from_scenario_adds_known_walls_and_posts_and_all_of_them_when_asked():
    from rovernav.scenario import parse_scenario

    sc = parse_scenario("""version = 1
[arena]
width_m = 2.0
height_m = 1.5
[start]
x_m = 0.3
y_m = 0.3
[target]
x_m = 1.7
y_m = 1.2
[[walls]]
x0_m = 0.6
y0_m = 0.2
x1_m = 1.1
y1_m = 0.9
thickness_m = 0.05
[[walls]]
x0_m = 1.4
y0_m = 0.0
x1_m = 1.4
y1_m = 0.8
thickness_m = 0.05
known = false
[[posts]]
x_m = 0.5
y_m = 1.1
radius_m = 0.05
[[posts]]
x_m = 1.6
y_m = 1.0
radius_m = 0.04
known = false
""")
    known = OccupancyGrid.from_scenario(sc)
    every = OccupancyGrid.from_scenario(sc, all_obstacles=True)
    by_hand = OccupancyGrid(2.0, 1.5)
    by_hand.add_wall(0.6, 0.2, 1.1, 0.9, 0.05)
    by_hand.add_post(0.5, 1.1, 0.05)
    assert (known.inflated == by_hand.inflated).all() and (known.raw == by_hand.raw).all()
    by_hand.add_wall(1.4, 0.0, 1.4, 0.8, 0.05)
    by_hand.add_post(1.6, 1.0, 0.04)
    assert (every.inflated == by_hand.inflated).all() and (every.raw == by_hand.raw).all()
    assert not known.is_free(0.85, 0.55) and not known.is_free(0.5, 1.1)
    assert known.is_free(1.4, 0.4) and not every.is_free(1.4, 0.4)
    copy = every.copy()
    assert copy.walls == every.walls and copy.posts == every.posts and copy.walls is not every.walls
    assert (copy.blocked_within(0.17) == every.blocked_within(0.17)).all()
    result = plan(every, sc.start.xy, sc.target.xy)
    assert sampled_cells_free(every.inflated, every.resolution_m, result.waypoints)
