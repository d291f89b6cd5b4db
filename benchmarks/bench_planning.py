"""Grid build + A* against the previous implementation and scipy's csgraph Dijkstra on the same 16-direction graph.

    python benchmarks/bench_planning.py [--runs N] [--no-plain]

Cases: the seed's arena (2.36 × 1.75 m at 0.03 m) with the large and the small obstacles
(all of them known); a generated 20 × 20 m arena at 0.05 m with 40 random boxes (400 × 400
cells, fixed seed); and a generated 50 × 50 m arena at 0.05 m with 250 random boxes (1000 ×
1000 cells: the same resolution and the same density of boxes, 0.1 a square metre, fixed
seed), start and goal in opposite corners.

ours: building the occupancy grid from the obstacles, then `plan()` (A*, compiled with numba,
plus the waypoint simplification). prev.: the same with the implementation before issue 29 —
the grid's box inflation with numpy's distances (and its wall band from the (ny, nx) distances)
and `astar_cells_reference` in plan() — timed in the same run, alternating with ours run by
run; ×prev. is prev. / ours, ×A* the A* kernel's alone (astar_cells_reference / astar_cells).
Both must give the same layers, and the same path cell for cell, or the run fails. scipy: the
same grid, then building the 16-move graph from it (vectorised numpy, the same move rule) and
`scipy.sparse.csgraph.dijkstra` from the start; the graph's construction counts in its time,
and it must find the same optimal cost. Times are medians over the runs, after one warm-up (the
A*'s workspace is then allocated: a plan on a grid of a new size first pays numpy's np.empty
of 29 B a cell). The plain-Python column runs the very A* kernel uncompiled, once, to show what
the compiler buys. target: the issue's bound on ours (issue 29).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

import rovernav.planning.planner as planner_module  # noqa: E402
from rovernav.planning import OccupancyGrid, PlannerConfig, plan, warm_up  # noqa: E402
from rovernav.planning._jit import COMPILED  # noqa: E402
from rovernav.planning.astar import astar_cells, astar_cells_reference  # noqa: E402
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
    """(name, size [m], config, boxes, start, goal, target [ms] for ours)."""
    for name in ("seed-large-obstacles", "seed-small-obstacles"):
        s = load_scenario(name)
        boxes = [(o.x_m, o.y_m, o.w_m, o.h_m) for o in s.obstacles]
        yield name, (s.arena.width_m, s.arena.height_m), PlannerConfig(), boxes, s.start.xy, s.target.xy, 0.25
    for size_m, n_boxes, target_ms in ((20.0, 40, 2.0), (50.0, 250, 20.0)):
        start, goal = (0.6, 0.6), (size_m - 0.6, size_m - 0.6)
        yield (
            f"generated {size_m:.0f} × {size_m:.0f} m, {n_boxes} boxes",
            (size_m, size_m),
            PlannerConfig(resolution_m=0.05),
            generated_boxes(n_boxes, size_m, seed=2024, keep_clear=[start, goal]),
            start,
            goal,
            target_ms,
        )


def build(size, config, boxes) -> OccupancyGrid:
    grid = OccupancyGrid(*size, config)
    for box in boxes:
        grid.add_box(*box)
    return grid


def build_previous(size, config, boxes) -> OccupancyGrid:
    """`build` as before issue 29: the wall band from the (ny, nx) wall distances, and each box
    (add_box's cells, then its inflation) with numpy's distances (`_box_distance`, `_grow`)."""
    grid = OccupancyGrid(*size, config)
    grid.inflated = grid.wall_distance() <= config.inflation_m + 1e-12
    res = grid.resolution_m
    for x_m, y_m, w_m, h_m in boxes:
        box = (float(x_m), float(y_m), float(w_m), float(h_m))
        c0, c1 = max(math.floor((x_m - w_m / 2) / res), 0), min(math.ceil((x_m + w_m / 2) / res), grid.nx)
        r0, r1 = max(math.floor((y_m - h_m / 2) / res), 0), min(math.ceil((y_m + h_m / 2) / res), grid.ny)
        grid.raw[r0 : max(r1, r0), c0 : max(c1, c0)] = True
        grid.boxes.append(box)
        grid.version += 1
        grid._grow(grid._box_distance(box, config.inflation_m))
    return grid


@contextlib.contextmanager
def previous_astar():
    """plan() with the A* kernel before issue 29."""
    planner_module.astar_cells = astar_cells_reference
    try:
        yield
    finally:
        planner_module.astar_cells = astar_cells


def plan_previous(grid, start, goal):
    with previous_astar():
        return plan(grid, start, goal)


def timed(fn, runs: int) -> tuple[float, object]:
    fn()  # warm-up
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), out


def timed_pair(fn_a, fn_b, runs: int) -> tuple[float, float, object, object]:
    """Medians [ms] of fn_a and fn_b, run alternately (the machine's load falls on both alike)."""
    out_a, out_b = fn_a(), fn_b()  # warm-up
    times_a, times_b = [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        out_a = fn_a()
        t1 = time.perf_counter()
        out_b = fn_b()
        t2 = time.perf_counter()
        times_a.append((t1 - t0) * 1e3)
        times_b.append((t2 - t1) * 1e3)
    return statistics.median(times_a), statistics.median(times_b), out_a, out_b


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=21, help="timed runs per case (default 21)")
    parser.add_argument("--no-plain", action="store_true", help="skip the plain-Python run")
    parser.add_argument("--json", type=Path, help="also write each case's figures here (benchmarks/speed_table.py)")
    args = parser.parse_args()
    rows = []
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
        f"{'case':<32} {'cells':>9} {'grid':>6} {'A*':>6} {'ours':>6} {'target':>7} {'exp.':>6} {'cost m':>8} "
        f"{'wp':>3} | {'prev.':>6} {'×prev.':>6} {'×A*':>5} | {'graph':>6} {'dijk.':>6} {'scipy':>6} "
        f"{'×scipy':>6} {'cost m':>8} | {'plain Py':>8}"
    )
    print(header)
    print("-" * len(header))
    failed = False
    for name, size, config, boxes, start, goal, target_ms in cases():
        grid = build(size, config, boxes)
        old_grid = build_previous(size, config, boxes)
        if not ((grid.inflated == old_grid.inflated).all() and (grid.raw == old_grid.raw).all()):
            print(f"{name}: the grid differs from the previous implementation's")
            return 1
        s_cell, g_cell = grid.world_to_cell(*start), grid.world_to_cell(*goal)
        grid_ms, _ = timed(lambda: build(size, config, boxes), args.runs)
        astar_ms, result = timed(lambda: plan(grid, start, goal), args.runs)
        ours_ms, prev_ms, _, prev_result = timed_pair(
            lambda: plan(build(size, config, boxes), start, goal),
            lambda: plan_previous(build_previous(size, config, boxes), start, goal),
            args.runs,
        )
        kernel_ms, kernel_prev_ms, (path, cost, _), (prev_path, prev_cost, _) = timed_pair(
            lambda: astar_cells(grid.inflated, *s_cell, *g_cell),
            lambda: astar_cells_reference(grid.inflated, *s_cell, *g_cell),
            args.runs,
        )
        identical = (
            np.array_equal(path, prev_path)
            and cost == prev_cost
            and np.array_equal(result.cells, prev_result.cells)
            and result.waypoints == prev_result.waypoints
            and result.expansions == prev_result.expansions
        )
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
        met = "ok" if ours_ms <= target_ms else "MISSED"
        print(
            f"{name:<32} {f'{grid.nx}×{grid.ny}':>9} {grid_ms:6.2f} {astar_ms:6.2f} {ours_ms:6.2f} "
            f"{f'≤{target_ms:g} ' + ('' if met == 'ok' else '!'):>7} {result.expansions:6d} {result.cost_m:8.4f} "
            f"{len(result.waypoints):3d} | {prev_ms:6.2f} {prev_ms / ours_ms:6.1f} {kernel_prev_ms / kernel_ms:5.1f} | "
            f"{graph_ms:6.1f} {dijkstra_ms:6.1f} {scipy_ms:6.1f} {scipy_ms / ours_ms:6.0f} {scipy_cost * res:8.4f} | "
            f"{plain:>8}"
            + ("" if same else "   COSTS DIFFER")
            + ("" if identical else "   PATH DIFFERS FROM THE PREVIOUS IMPLEMENTATION'S")
            + ("" if met == "ok" else f"   ABOVE THE TARGET OF {target_ms:g} ms")
        )
        if not (same and identical):
            return 1
        failed = failed or met != "ok"
        rows.append(
            {
                "case": name,
                "cells": f"{grid.nx}×{grid.ny}",
                "ours_ms": ours_ms,
                "previous_ms": prev_ms,
                "astar_ms": astar_ms,
                "grid_ms": grid_ms,
                "scipy_ms": scipy_ms,
                "target_ms": target_ms,
            }
        )
    print(
        "\ngrid: building the occupancy grid from the boxes; A*: plan() on it (search + simplification);"
        "\nours: both; target: issue 29's bound on ours (! missed); exp.: cells A* expanded;"
        "\nwp: waypoints after simplification;"
        "\nprev.: grid + plan() as before issue 29, alternating with ours; ×prev.: prev. / ours;"
        "\n×A*: the A* kernel before / now, alone (astar_cells_reference / astar_cells, alternating);"
        "\ngraph+dijk.: scipy on our grid (graph built from it, then Dijkstra from the start);"
        "\nscipy: grid + graph + Dijkstra; ×scipy: scipy / ours; plain Py: our A* kernel uncompiled, one run."
    )
    if args.json:
        args.json.write_text(json.dumps({"runs": args.runs, "cases": rows}, indent=1))
    return 2 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
