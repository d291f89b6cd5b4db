"""Grid build + A* against scipy's csgraph Dijkstra on the same 16-direction graph.

    python benchmarks/bench_planning.py [--runs N]

Cases: the seed's arena (2.36 × 1.75 m at 0.03 m) with the large and the small obstacles
(all of them known), and a generated 20 × 20 m arena at 0.05 m with 40 random boxes (fixed
seed). Ours: building the occupancy grid from the obstacles, then `plan()` (A*, compiled with
numba, plus the waypoint simplification). scipy: the same grid, then building the 16-move
graph from it (vectorised numpy, the same move rule) and `scipy.sparse.csgraph.dijkstra` from
the start; the graph's construction counts in its time. Times are medians over the runs,
after one warm-up; both must find the same optimal cost. The plain-Python column runs the
very A* kernel uncompiled, once, to show what the compiler buys.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from rovernav.planning import OccupancyGrid, PlannerConfig, plan, warm_up  # noqa: E402
from rovernav.planning._jit import COMPILED  # noqa: E402
from rovernav.planning.astar import astar_cells  # noqa: E402
from rovernav.planning.moves import MID1_DX, MID1_DY, MID2_DX, MID2_DY, MOVE_COST, MOVE_DX, MOVE_DY  # noqa: E402
from rovernav.scenario import load_scenario  # noqa: E402


def csgraph_graph(blocked: np.ndarray):
    """The 16-move graph of `blocked` as a scipy CSR matrix (vectorised numpy, the planner's move rule)."""
    from scipy.sparse import csr_matrix

    ny, nx = blocked.shape
    pad = 2
    free = np.zeros((ny + 2 * pad, nx + 2 * pad), dtype=bool)
    free[pad:-pad, pad:-pad] = ~blocked

    def shifted(dx: int, dy: int) -> np.ndarray:
        return free[pad + dy : pad + dy + ny, pad + dx : pad + dx + nx]

    index = np.arange(nx * ny).reshape(ny, nx)
    src, dst, cost = [], [], []
    for k in range(len(MOVE_DX)):
        ok = (
            shifted(0, 0)
            & shifted(MOVE_DX[k], MOVE_DY[k])
            & shifted(MID1_DX[k], MID1_DY[k])
            & shifted(MID2_DX[k], MID2_DY[k])
        )
        s = index[ok]
        src.append(s)
        dst.append(s + MOVE_DY[k] * nx + MOVE_DX[k])
        cost.append(np.full(len(s), MOVE_COST[k]))
    return csr_matrix((np.concatenate(cost), (np.concatenate(src), np.concatenate(dst))), shape=(nx * ny, nx * ny))


def csgraph_cost(graph, nx: int, start: tuple[int, int], goal: tuple[int, int]) -> float:
    """scipy's Dijkstra from start over the whole graph; the goal's cost [cells]."""
    from scipy.sparse.csgraph import dijkstra

    return float(dijkstra(graph, indices=start[1] * nx + start[0])[goal[1] * nx + goal[0]])


def generated_boxes(n: int, size_m: float, seed: int, keep_clear: list[tuple[float, float]]):
    rng = np.random.default_rng(seed)
    boxes = []
    while len(boxes) < n:
        x, y = rng.uniform(0.5, size_m - 0.5, 2)
        w, h = rng.uniform(0.3, 2.0, 2)
        if all(abs(x - cx) > w / 2 + 0.5 or abs(y - cy) > h / 2 + 0.5 for cx, cy in keep_clear):
            boxes.append((x, y, w, h))
    return boxes


def cases():
    for name in ("seed-large-obstacles", "seed-small-obstacles"):
        s = load_scenario(name)
        boxes = [(o.x_m, o.y_m, o.w_m, o.h_m) for o in s.obstacles]
        yield name, (s.arena.width_m, s.arena.height_m), PlannerConfig(), boxes, s.start.xy, s.target.xy
    start, goal = (0.6, 0.6), (19.4, 19.4)
    yield (
        "generated 20 × 20 m, 40 boxes",
        (20.0, 20.0),
        PlannerConfig(resolution_m=0.05),
        generated_boxes(40, 20.0, seed=2024, keep_clear=[start, goal]),
        start,
        goal,
    )


def build(size, config, boxes) -> OccupancyGrid:
    grid = OccupancyGrid(*size, config)
    for box in boxes:
        grid.add_box(*box)
    return grid


def timed(fn, runs: int) -> tuple[float, object]:
    fn()  # warm-up
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=21, help="timed runs per case (default 21)")
    parser.add_argument("--no-plain", action="store_true", help="skip the plain-Python run")
    args = parser.parse_args()
    warm_up()

    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    import numba
    import scipy

    print(
        f"cores: {os.cpu_count()} ({affinity} usable); Python {platform.python_version()}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, numba {numba.__version__} (A* compiled: {COMPILED})"
    )
    print(f"median of {args.runs} runs after a warm-up, in ms; cost = the optimal path's length on the grid\n")
    header = (
        f"{'case':<32} {'cells':>9} {'grid':>6} {'A*':>6} {'ours':>7} {'exp.':>7} {'cost m':>8} {'wp':>3} | "
        f"{'graph':>7} {'dijk.':>7} {'scipy':>7} {'cost m':>8} | {'plain Py':>8}"
    )
    print(header)
    print("-" * len(header))
    for name, size, config, boxes, start, goal in cases():
        grid = build(size, config, boxes)
        s_cell, g_cell = grid.world_to_cell(*start), grid.world_to_cell(*goal)
        grid_ms, _ = timed(lambda: build(size, config, boxes), args.runs)
        astar_ms, result = timed(lambda: plan(grid, start, goal), args.runs)
        ours_ms, _ = timed(lambda: plan(build(size, config, boxes), start, goal), args.runs)
        few = max(3, args.runs // 3)
        graph_ms, graph = timed(lambda: csgraph_graph(grid.inflated), few)
        dijkstra_ms, _ = timed(lambda: csgraph_cost(graph, grid.nx, s_cell, g_cell), few)
        scipy_ms, scipy_cost = timed(
            lambda: csgraph_cost(csgraph_graph(build(size, config, boxes).inflated), grid.nx, s_cell, g_cell), few
        )
        res = grid.resolution_m
        same = abs(scipy_cost * res - result.cost_m) < 1e-6
        plain = "skipped"
        if not args.no_plain:
            t0 = time.perf_counter()
            _, plain_cost, _ = astar_cells.py_func(grid.inflated, *s_cell, *g_cell)
            plain = f"{(time.perf_counter() - t0) * 1e3:8.0f}"
            same = same and abs(plain_cost * res - result.cost_m) < 1e-6
        print(
            f"{name:<32} {f'{grid.nx}×{grid.ny}':>9} {grid_ms:6.2f} {astar_ms:6.2f} {ours_ms:7.2f} "
            f"{result.expansions:7d} {result.cost_m:8.4f} {len(result.waypoints):3d} | "
            f"{graph_ms:7.1f} {dijkstra_ms:7.1f} {scipy_ms:7.1f} {scipy_cost * res:8.4f} | {plain:>8}"
            + ("" if same else "   COSTS DIFFER")
        )
        if not same:
            return 1
    print(
        "\ngrid: building the occupancy grid from the boxes; A*: plan() on it (search + simplification);"
        "\nours: both; exp.: cells A* expanded; wp: waypoints after simplification;"
        "\ngraph+dijk.: scipy on our grid (graph built from it, then Dijkstra from the start);"
        "\nscipy: grid + graph + Dijkstra; plain Py: our A* kernel uncompiled, one run."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
