"""Planning: the 16-move motion model, the segment check, and A*'s optimality on its grid.

A*'s optimality is checked against a Dijkstra written plainly here, over the same 16 moves,
with the cells each move touches found independently (by sampling the segment), and against
scipy's csgraph on a larger grid; and its search against the implementation before issue 29
(`astar_cells_reference`), cell for cell, on random grids, boxes, mazes, empty grids and
grids with no way through.

The rest of what was test_planning.py: test_planning_grid.py (the occupancy grid),
test_planning_paths.py (plans on the shared scenarios, Table 4.2, errors), test_planning_cli.py
(`rovernav plan`).
"""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests.planning_checks import sampled_cells_free

from rovernav.planning import OccupancyGrid, PlannerConfig
from rovernav.planning.astar import astar_cells, astar_cells_reference, path_cost
from rovernav.planning.moves import MOVE_DX, MOVE_DY, N_MOVES, free_space_distance, move_allowed
from rovernav.planning.segment import segment_clear

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
@given(seed=st.integers(0, 2**32 - 1), nx=st.integers(1, 11), ny=st.integers(1, 11), density=st.floats(0.0, 0.5))
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
        blocked[y : y + rng.integers(2, 12), x : x + rng.integers(2, 12)] = True
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


# --- the search is the previous implementation's, cell for cell ------------------------------------
# astar_cells (issue 29: padded grid, state bytes, a reused workspace, keys in the heap) must expand
# the same cells in the same order as astar_cells_reference, so every path, cost and expansion count
# is the same, ties included: the missions must not change at all.


def assert_same_search(blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> None:
    path, cost, expansions = astar_cells(blocked, *start, *goal)
    ref_path, ref_cost, ref_expansions = astar_cells_reference(blocked, *start, *goal)
    assert path.tolist() == ref_path.tolist(), (blocked.shape, start, goal)
    assert cost == ref_cost and expansions == ref_expansions, (blocked.shape, start, goal)
    assert path.dtype == ref_path.dtype and path.shape[1:] == (2,)


def box_grid(rng: np.random.Generator, nx: int, ny: int, n_boxes: int) -> np.ndarray:
    blocked = np.zeros((ny, nx), dtype=bool)
    for _ in range(n_boxes):
        x, y = rng.integers(0, nx), rng.integers(0, ny)
        blocked[y : y + rng.integers(1, max(2, nx // 4)), x : x + rng.integers(1, max(2, ny // 4))] = True
    return blocked


def maze_grid(rng: np.random.Generator, nx_rooms: int, ny_rooms: int, extra_openings: int) -> np.ndarray:
    """A perfect maze (depth-first carving) on (2·n + 1) cells a side, then a few more walls knocked
    through so that there are loops (and equal-cost ways round them)."""
    blocked = np.ones((2 * ny_rooms + 1, 2 * nx_rooms + 1), dtype=bool)
    seen = np.zeros((ny_rooms, nx_rooms), dtype=bool)
    stack = [(0, 0)]
    seen[0, 0] = True
    blocked[1, 1] = False
    while stack:
        x, y = stack[-1]
        nexts = [
            (x + dx, y + dy)
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= x + dx < nx_rooms and 0 <= y + dy < ny_rooms and not seen[y + dy, x + dx]
        ]
        if not nexts:
            stack.pop()
            continue
        x1, y1 = nexts[rng.integers(len(nexts))]
        seen[y1, x1] = True
        blocked[2 * y1 + 1, 2 * x1 + 1] = False
        blocked[y + y1 + 1, x + x1 + 1] = False
        stack.append((x1, y1))
    ny, nx = blocked.shape
    for _ in range(extra_openings):
        blocked[rng.integers(1, ny - 1), rng.integers(1, nx - 1)] = False
    return blocked


def free_cells(blocked: np.ndarray) -> list[tuple[int, int]]:
    return [(int(x), int(y)) for y, x in np.argwhere(~blocked)]


def some_ends(rng: np.random.Generator, blocked: np.ndarray, n: int) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """n random (start, goal) pairs of free cells, and the free corners and edge cells paired up."""
    free = free_cells(blocked)
    if not free:
        return []
    pairs = [(free[rng.integers(len(free))], free[rng.integers(len(free))]) for _ in range(n)]
    ny, nx = blocked.shape
    rim = [
        c
        for c in ((0, 0), (nx - 1, 0), (0, ny - 1), (nx - 1, ny - 1), (nx // 2, 0), (0, ny // 2))
        if not blocked[c[1], c[0]]
    ]
    pairs += [(a, b) for a in rim for b in rim]  # start == goal among them
    return pairs


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), nx=st.integers(1, 40), ny=st.integers(1, 40), density=st.floats(0.0, 0.6))
def test_the_search_is_the_reference_search_on_random_grids(seed, nx, ny, density):
    blocked, start, goal = random_grid(seed, nx, ny, density)
    assert_same_search(blocked, start, goal)
    assert_same_search(blocked, goal, start)


def test_the_search_is_the_reference_search_on_many_generated_grids():
    rng = np.random.default_rng(29)
    checked = unreachable = 0
    grids = []
    for _ in range(60):  # boxes, as the arenas have them
        nx, ny = rng.integers(2, 120, 2)
        grids.append(box_grid(rng, nx, ny, rng.integers(0, 30)))
    for _ in range(30):  # mazes, with and without loops
        grids.append(maze_grid(rng, rng.integers(1, 30), rng.integers(1, 30), rng.integers(0, 40)))
    for nx, ny in ((1, 1), (1, 17), (23, 1), (2, 2), (5, 3), (64, 64), (97, 31)):  # empty: ties everywhere
        grids.append(np.zeros((ny, nx), dtype=bool))
    wall = np.zeros((40, 50), dtype=bool)
    wall[:, 24] = True  # no way across
    grids.append(wall)
    corner = np.zeros((40, 50), dtype=bool)
    corner[20, :26] = True
    corner[:21, 25] = True  # a closed room: reachable only from inside
    grids.append(corner)
    for blocked in grids:
        for start, goal in some_ends(rng, blocked, 6):
            assert_same_search(blocked, start, goal)
            checked += 1
            unreachable += astar_cells(blocked, *start, *goal)[1] == -1.0
    assert checked > 1500 and unreachable > 20


def test_the_search_is_the_reference_search_on_the_benchmarks_400_by_400_arena():
    rng = np.random.default_rng(2024)
    grid = OccupancyGrid(20.0, 20.0, PlannerConfig(resolution_m=0.05))
    while len(grid.boxes) < 40:
        x, y = rng.uniform(0.5, 19.5, 2)
        w, h = rng.uniform(0.3, 2.0, 2)
        if all(abs(x - c) > w / 2 + 0.5 or abs(y - c) > h / 2 + 0.5 for c in (0.6, 19.4)):
            grid.add_box(x, y, w, h)
    ends = [(grid.world_to_cell(0.6, 0.6), grid.world_to_cell(19.4, 19.4))]
    ends += some_ends(rng, grid.inflated, 4)[:4]
    for start, goal in ends:
        assert_same_search(grid.inflated, start, goal)


def test_the_search_outside_its_contract_is_still_the_reference_search():
    """A blocked start (plan() refuses it first) and a non-contiguous grid: the same answers."""
    rng = np.random.default_rng(5)
    blocked = box_grid(rng, 30, 20, 12)
    blocked[3, 4] = True
    assert_same_search(blocked, (4, 3), (25, 15))
    assert_same_search(blocked, (25, 15) if not blocked[15, 25] else (0, 0), (4, 3))
    wide = box_grid(rng, 60, 40, 20)
    assert_same_search(wide[::2, ::3], (0, 0), (19, 19))
    assert_same_search(np.asfortranarray(wide), (1, 1), (58, 38))


def test_the_search_gives_each_thread_its_own_workspace():
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(11)
    cases = [(box_grid(rng, n, n, n // 3), (0, 0), (n - 1, n - 1)) for n in (150, 90, 150, 40) * 4]
    expected = [astar_cells_reference(b, *s, *g) for b, s, g in cases]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda c: astar_cells(c[0], *c[1], *c[2]), cases))
    for (path, cost, expansions), (ref_path, ref_cost, ref_expansions) in zip(got, expected):
        assert path.tolist() == ref_path.tolist() and cost == ref_cost and expansions == ref_expansions
