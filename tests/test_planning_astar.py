"""Planning: the occupancy grid, A*, simplification, the potential field, sonar echoes and `rovernav plan`.

A*'s optimality is checked against a Dijkstra written plainly here, over the same 16 moves,
with the cells each move touches found independently (by sampling the segment), and against
scipy's csgraph on a larger grid.
"""
from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rovernav.planning import OccupancyGrid, PlannerConfig, plan
from rovernav.planning.astar import astar_cells, path_cost
from rovernav.planning.moves import MOVE_DX, MOVE_DY, N_MOVES, free_space_distance, move_allowed
from rovernav.planning.segment import segment_clear

from tests.planning_checks import sampled_cells_free, scenario_grid

# --- an independent model of the 16 moves -----------------------------------------------------

# 8 neighbours and 8 knight moves: every (dx, dy) whose squared length is 1, 2 or 5.
MOVES = [(dx, dy) for dx in range(-2, 3) for dy in range(-2, 3) if dx * dx + dy * dy in (1, 2, 5)]


def touched_cells(dx: int, dy: int) -> set[tuple[int, int]]:
    """Cells (relative to the start cell) the closed segment between the two centres touches, by sampling.

    Each sample is also nudged a hair in x and y, so a segment through a grid corner touches
    the four cells around it.
    """
    cells = set()
    for i in range(401):
        x, y = 0.5 + dx * i / 400, 0.5 + dy * i / 400
        for ex in (-1e-7, 0.0, 1e-7):
            for ey in (-1e-7, 0.0, 1e-7):
                cells.add((math.floor(x + ex), math.floor(y + ey)))
    return cells


TOUCHED = {m: touched_cells(*m) for m in MOVES}


def edge_ok(blocked: np.ndarray, x: int, y: int, move: tuple[int, int]) -> bool:
    ny, nx = blocked.shape
    return all(0 <= x + cx < nx and 0 <= y + cy < ny and not blocked[y + cy, x + cx] for cx, cy in TOUCHED[move])


def dijkstra_cost(blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> float | None:
    best = {start: 0.0}
    heap = [(0.0, start)]
    done = set()
    while heap:
        d, cell = heapq.heappop(heap)
        if cell in done:
            continue
        done.add(cell)
        if cell == goal:
            return d
        x, y = cell
        for move in MOVES:
            if edge_ok(blocked, x, y, move):
                nxt = (x + move[0], y + move[1])
                nd = d + math.hypot(*move)
                if nd < best.get(nxt, math.inf):
                    best[nxt] = nd
                    heapq.heappush(heap, (nd, nxt))
    return None


def random_grid(seed: int, nx: int, ny: int, density: float):
    rng = np.random.default_rng(seed)
    blocked = rng.random((ny, nx)) < density
    free = np.argwhere(~blocked)
    if len(free) == 0:
        blocked[0, 0] = False
        free = np.argwhere(~blocked)
    (sy, sx), (gy, gx) = free[rng.integers(len(free))], free[rng.integers(len(free))]
    return blocked, (int(sx), int(sy)), (int(gx), int(gy))


# --- the motion model and the segment check ---------------------------------------------------

def test_the_motion_model_is_the_seeds_16_directions():
    ours = sorted(zip(MOVE_DX.tolist(), MOVE_DY.tolist()))
    assert ours == sorted(MOVES) and N_MOVES == 16


def test_a_knight_move_crosses_two_cells_besides_its_ends():
    assert TOUCHED[(2, 1)] == {(0, 0), (1, 0), (1, 1), (2, 1)}
    assert TOUCHED[(1, 1)] == {(0, 0), (1, 0), (0, 1), (1, 1)}
    for mid in ((1, 0), (1, 1)):
        blocked = np.zeros((2, 3), dtype=bool)
        blocked[mid[1], mid[0]] = True
        assert not move_allowed(blocked, 0, 0, list(zip(MOVE_DX, MOVE_DY)).index((2, 1)))


def test_a_diagonal_does_not_cut_the_corner_of_a_blocked_cell():
    blocked = np.array([[False, True], [False, False]])  # [iy, ix]: cell (1, 0) is blocked
    path, cost, _ = astar_cells(blocked, 0, 0, 1, 1)
    assert cost == pytest.approx(2.0)
    assert path.tolist() == [[0, 0], [0, 1], [1, 1]]
    assert not segment_clear(blocked, 0.5, 0.5, 1.5, 1.5)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), density=st.floats(0.0, 0.5))
def test_every_move_is_allowed_exactly_when_its_segment_is_clear(seed, density):
    blocked, _, _ = random_grid(seed, 7, 6, density)
    for y in range(6):
        for x in range(7):
            if blocked[y, x]:
                continue
            for k in range(N_MOVES):
                dx, dy = int(MOVE_DX[k]), int(MOVE_DY[k])
                expected = edge_ok(blocked, x, y, (dx, dy))
                assert move_allowed(blocked, x, y, k) == expected
                if 0 <= x + dx < 7 and 0 <= y + dy < 6:
                    assert segment_clear(blocked, x + 0.5, y + 0.5, x + dx + 0.5, y + dy + 0.5) == expected


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), density=st.floats(0.0, 0.45))
def test_segment_clear_agrees_with_fine_sampling_for_arbitrary_segments(seed, density):
    rng = np.random.default_rng(seed)
    blocked = rng.random((8, 8)) < density
    a, b = rng.uniform(0, 8, 2), rng.uniform(0, 8, 2)
    clear = segment_clear(blocked, a[0], a[1], b[0], b[1])
    samples_free = sampled_cells_free(blocked, 1.0, [a, b])
    # The check is conservative: it never passes a segment that sampling finds blocked.
    if clear:
        assert samples_free


def test_the_heuristic_is_the_exact_distance_on_an_empty_grid():
    empty = np.zeros((9, 9), dtype=bool)
    for gx in range(9):
        for gy in range(9):
            _, cost, _ = astar_cells(empty, 0, 0, gx, gy)
            assert free_space_distance(gx, gy) == pytest.approx(cost)
            assert free_space_distance(gx, gy) >= math.hypot(gx, gy) - 1e-12


# --- A* is optimal on its grid -------------------------------------------------------------------

@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), nx=st.integers(1, 11), ny=st.integers(1, 11),
       density=st.floats(0.0, 0.5))
def test_astar_finds_the_brute_force_optimum_on_random_grids(seed, nx, ny, density):
    blocked, start, goal = random_grid(seed, nx, ny, density)
    expected = dijkstra_cost(blocked, start, goal)
    path, cost, expansions = astar_cells(blocked, *start, *goal)
    if expected is None:
        assert len(path) == 0 and cost == -1.0
        return
    assert cost == pytest.approx(expected, abs=1e-6)
    assert tuple(path[0]) == start and tuple(path[-1]) == goal
    assert path_cost(path) == pytest.approx(cost, abs=1e-9)
    for (x0, y0), (x1, y1) in zip(path[:-1].tolist(), path[1:].tolist()):
        assert (x1 - x0, y1 - y0) in TOUCHED and edge_ok(blocked, x0, y0, (x1 - x0, y1 - y0))
    assert expansions >= 1


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), density=st.floats(0.0, 0.4))
def test_the_plain_python_kernel_gives_the_compiled_answer(seed, density):
    blocked, start, goal = random_grid(seed, 9, 7, density)
    compiled = astar_cells(blocked, *start, *goal)
    plain = astar_cells.py_func(blocked, *start, *goal)
    assert plain[1] == pytest.approx(compiled[1])
    assert len(plain[0]) == len(compiled[0])


def test_astar_matches_scipy_dijkstra_on_a_larger_grid():
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    rng = np.random.default_rng(7)
    blocked = np.zeros((70, 90), dtype=bool)
    for _ in range(25):
        x, y = rng.integers(0, 90), rng.integers(0, 70)
        blocked[y:y + rng.integers(2, 12), x:x + rng.integers(2, 12)] = True
    ny, nx = blocked.shape
    rows, cols, costs = [], [], []
    for y in range(ny):
        for x in range(nx):
            if blocked[y, x]:
                continue
            for move in MOVES:
                if edge_ok(blocked, x, y, move):
                    rows.append(y * nx + x)
                    cols.append((y + move[1]) * nx + x + move[0])
                    costs.append(math.hypot(*move))
    graph = csr_matrix((costs, (rows, cols)), shape=(nx * ny, nx * ny))
    free = np.argwhere(~blocked)
    for _ in range(6):
        (sy, sx), (gy, gx) = free[rng.integers(len(free))], free[rng.integers(len(free))]
        expected = dijkstra(graph, indices=sy * nx + sx)[gy * nx + gx]
        _, cost, _ = astar_cells(blocked, int(sx), int(sy), int(gx), int(gy))
        if math.isinf(expected):
            assert cost == -1.0
        else:
            assert cost == pytest.approx(expected, abs=1e-6)


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
    for (x, y), blocked in [((1.0, 1.0), True), ((1.1 + margin - 0.02, 1.0), True),
                            ((1.1 + margin + 0.02, 1.0), False), ((1.0, 0.9 - margin + 0.02), True),
                            ((1.0, 0.9 - margin - 0.02), False),
                            # past the corner the margin is round: 0.12 m out on both axes is 0.17 m away
                            ((1.1 + 0.11, 1.1 + 0.11), True), ((1.1 + 0.13, 1.1 + 0.13), False)]:
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
        grid.add_disks(rng.uniform((0.3, 0.3), (2.7, 1.7), size=(int(rng.integers(1, 30)), 2)), rng.uniform(0.005, 0.03))
    assert (grid.inflated == grid.blocked_within(grid.config.inflation_m)).all()
    new, newly = grid.add_disks(np.array([[-0.1, -0.2], [3.5, 1.0]]), 0.02)   # off the arena: dropped
    assert len(new) == 0 and newly == 0


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
    sure = np.abs(bf - inflation) > 1e-3   # the sampled outline is within 0.25 mm of the true one
    assert ((grid.inflated == ((bf <= inflation) | wall_band)) | ~sure).all()
    assert (sure & ~wall_band).sum() > 500                     # the comparison covers many cells
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
