"""`plan()`: from a start to a target on an occupancy grid, with A*, Theta* or the potential field."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import numpy as np

from .astar import astar_cells, path_cost
from .config import PlannerConfig
from .errors import GoalBlocked, OutsideArena, StartBlocked, Unreachable
from .grid import OccupancyGrid
from .potential import body_layer, potential_cells
from .segment import polyline_clear
from .simplify import simplify_points
from .theta import refine_points, snap_to_corners, theta_points

PLANNERS = ("astar", "theta", "potential")


@dataclasses.dataclass(frozen=True)
class PlanResult:
    """A path from start to target.

    waypoints   (x, y) [m] the rover drives through, simplified; the first is the start and the
                last the target, exactly as given
    cells       the planner's raw path, an (n, 2) int array of cells (ix, iy), start to goal cell
                (Theta*: the cells holding its waypoints)
    length_m    length of the waypoint polyline [m]: what the rover drives
    cost_m      length of the raw cell path, centre to centre [m] (A*: the optimum on the grid);
                Theta*: the length of its any-angle path as driven (= length_m)
    time_s      time to search and simplify [s] (the grid's construction not included)
    expansions  A* and Theta*: cells taken off the open list; potential field: moves examined
    """

    planner: str
    waypoints: tuple[tuple[float, float], ...]
    cells: np.ndarray
    length_m: float
    cost_m: float
    time_s: float
    expansions: int


def warm_up() -> None:
    """Load the compiled kernels (compile them, the first time on a machine) before timing a
    search or a grid's build (add_box's inflation is compiled too).

    numba compiles on first use; from its on-disk cache that first call still costs about a
    quarter of a second, which would otherwise land in the first plan's `time_s`.
    """
    OccupancyGrid(0.09, 0.09, PlannerConfig(resolution_m=0.03)).add_box(0.045, 0.045, 0.01, 0.01)  # grid._grow_box
    blocked = np.zeros((3, 3), dtype=np.bool_)
    astar_cells(blocked, 0, 0, 2, 2)
    snap_to_corners(
        blocked, refine_points(blocked, theta_points(blocked, 0.5, 0.5, 2.5, 1.5)[0])
    )  # as plan() calls them
    simplify_points(blocked, np.array([[0.5, 0.5], [1.5, 1.5], [2.5, 2.5]]))
    polyline_clear(blocked, np.array([[0.5, 0.5], [2.5, 1.5]]))


def _polyline_length(points: np.ndarray) -> float:
    if len(points) < 2:
        return 0.0
    d = np.diff(points, axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def plan(
    grid: OccupancyGrid,
    start_xy: Sequence[float],
    goal_xy: Sequence[float],
    planner: str = "astar",
    simplify: bool = True,
) -> PlanResult:
    """Plan a path [m] from `start_xy` to `goal_xy`.

    planner: "astar" (optimal on the 16-direction grid; its path touches no inflated cell),
    "theta" (Lazy Theta*: any-angle segments, pulled taut and its corners snapped onto the
    blocked cells' corners; every segment
    touches no inflated cell, see `theta`) or "potential" (the seed's comparison; its path keeps
    the robot radius, see `potential`).
    The time counts the search and the simplification, and the potential field's map.
    Raises OutsideArena, StartBlocked, GoalBlocked, Unreachable or LocalMinimum (all
    NoPathError), and ValueError for an unknown planner.
    """
    if planner not in PLANNERS:
        raise ValueError(f"unknown planner {planner!r} (choose from {', '.join(PLANNERS)})")
    start = (float(start_xy[0]), float(start_xy[1]))
    goal = (float(goal_xy[0]), float(goal_xy[1]))
    for which, xy in (("start", start), ("target", goal)):
        if not (math.isfinite(xy[0]) and math.isfinite(xy[1])) or not grid.contains(*xy):
            raise OutsideArena(which, xy, grid.width_m, grid.height_m)
    t0 = time.perf_counter()
    if planner in ("astar", "theta"):
        blocked, clearance, what = grid.inflated, grid.config.inflation_m, "robot radius + sonar margin"
    else:
        blocked, clearance, what = body_layer(grid), grid.config.robot_radius_m, "robot radius"
    s_cell = grid.world_to_cell(*start)
    g_cell = grid.world_to_cell(*goal)
    if blocked[s_cell[1], s_cell[0]]:
        raise StartBlocked(start, clearance, what)
    if blocked[g_cell[1], g_cell[0]]:
        raise GoalBlocked(goal, clearance, what)

    res = grid.resolution_m
    if planner == "theta":
        ends = grid.to_cell_units([start, goal])
        points, _, expansions = theta_points(blocked, ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1])
        if len(points) == 0:
            raise Unreachable(start, goal)
        if simplify:
            points = simplify_points(blocked, snap_to_corners(blocked, refine_points(blocked, points)))
        cells = np.minimum(np.floor(points).astype(np.int64), [grid.nx - 1, grid.ny - 1])
        return _result(planner, grid, points * res, start, goal, cells, None, t0, expansions)
    if planner == "astar":
        cells, cost, expansions = astar_cells(blocked, s_cell[0], s_cell[1], g_cell[0], g_cell[1])
        if len(cells) == 0:
            raise Unreachable(start, goal)
    else:
        cells, expansions = potential_cells(grid, s_cell, g_cell, blocked)
        cost = path_cost(cells)
    # Start and target are inside their end cells, so joining them to those cells' centres
    # stays in free cells; the simplifier then drops whatever the rover can skip.
    points = grid.to_cell_units(np.concatenate([[start], grid.cells_to_world(cells), [goal]]))
    if simplify:
        points = simplify_points(blocked, points)
    else:
        keep = np.concatenate([[True], np.any(points[1:] != points[:-1], axis=1)])
        points = points[keep]
    return _result(planner, grid, points * res, start, goal, cells, float(cost) * res, t0, expansions)


def _result(planner, grid, waypoints, start, goal, cells, cost_m, t0, expansions) -> PlanResult:
    """The PlanResult of waypoints [m] (their ends set to start and goal exactly); cost_m None: their length."""
    waypoints[0] = start
    waypoints[-1] = goal
    if len(waypoints) == 1:
        waypoints = np.array([start, goal])
    length_m = _polyline_length(waypoints)
    elapsed = time.perf_counter() - t0
    return PlanResult(
        planner=planner,
        waypoints=tuple((float(x), float(y)) for x, y in waypoints),
        cells=np.asarray(cells, dtype=np.int64),
        length_m=length_m,
        cost_m=length_m if cost_m is None else cost_m,
        time_s=elapsed,
        expansions=int(expansions),
    )
