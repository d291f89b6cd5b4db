"""The seed's comparison planner: a potential field, descended greedily over the 16 moves.

As in PythonRobotics (Sakai et al. 2018), which the seed used: an attractive potential grows
with the distance to the target, a repulsive one rises near the nearest obstacle (or wall),
and the path steps downhill from cell to cell. Ours:

    U = k_att · d_target + k_rep · ((c₀ − c) / c₀)²   (the second term only while c < c₀)

d_target [m] is the distance to the target, c [m] the clearance: the distance to the nearest
obstacle or wall less the robot radius, and c₀ the influence distance. The repulsion is
bounded (k_rep at the body's edge) rather than PythonRobotics' ½·η·(1/c − 1/c₀)², which
soars in every narrow gap: in a sweep of gains, no setting of that form gave Table 4.2 from
starts moved a few centimetres, while this one does over a wide range (see `config`).
From each cell the descent takes the allowed move with the steepest fall of U per metre. U falls strictly at
every step, so the path cannot cycle; when no move lowers U short of the target the planner
is trapped in a local minimum and raises `LocalMinimum` — what the seed's Table 4.2 records
for the large obstacles.

Hard limit: the seed's potential field had none (only the repulsion kept it off obstacles).
Ours never lets the rover's body touch an obstacle: a move may not touch a cell whose centre
lies within the robot radius of an obstacle or the wall. The sonar's placement margin is
left to the repulsion, so a potential-field path may run closer to an obstacle than A*'s
inflated margin allows (its waypoints are simplified against the body layer too). With the
full margin the seed's small obstacles (0.08 m, 0.28 to 0.35 m apart) merge into one wall
from the bottom wall to near the top one, and no descent could reach the target there.
"""

from __future__ import annotations

import numpy as np

from .errors import LocalMinimum
from .grid import OccupancyGrid
from .moves import MOVE_COST, MOVE_DX, MOVE_DY, N_MOVES, move_allowed


def body_layer(grid: OccupancyGrid) -> np.ndarray:
    """Cells whose centre lies within the robot radius of an obstacle or the wall: the body's hard limit.

    A grid made from layers (no obstacle geometry) has only its inflated layer to go by.
    """
    if not grid.geometric:
        return grid.inflated
    return grid.blocked_within(grid.config.robot_radius_m)


def potential_map(grid: OccupancyGrid, goal_cell: tuple[int, int]) -> np.ndarray:
    """U at every cell centre, an (ny, nx) float array (dimensionless)."""
    cfg = grid.config
    gx, gy = grid.cell_to_world(*goal_cell)
    u = cfg.potential_attractive_gain * np.hypot(grid.xs[None, :] - gx, grid.ys[:, None] - gy)
    c0, body = cfg.potential_influence_m, cfg.robot_radius_m
    nearest = np.minimum(grid.obstacle_distance(body + c0), grid.wall_distance())
    clearance = np.maximum(nearest - body, 0.0)
    u += np.where(clearance < c0, cfg.potential_repulsive_gain * ((c0 - clearance) / c0) ** 2, 0.0)
    return u


def potential_cells(
    grid: OccupancyGrid, start_cell: tuple[int, int], goal_cell: tuple[int, int], blocked: np.ndarray
) -> tuple[np.ndarray, int]:
    """Descend U from start to goal cell over `blocked`: returns (cells (n, 2) of (ix, iy), moves examined).

    Raises LocalMinimum at the first cell with no lower allowed neighbour.
    """
    u = potential_map(grid, goal_cell)
    x, y = start_cell
    path = [(x, y)]
    examined = 0
    while (x, y) != goal_cell:
        here = u[y, x]
        best_k, best_slope = -1, 0.0
        for k in range(N_MOVES):
            examined += 1
            if not move_allowed(blocked, x, y, k):
                continue
            nx_, ny_ = x + int(MOVE_DX[k]), y + int(MOVE_DY[k])
            if (nx_, ny_) == goal_cell:
                best_k = k
                break
            slope = (here - u[ny_, nx_]) / MOVE_COST[k]
            if slope > best_slope:
                best_k, best_slope = k, slope
        if best_k < 0:
            raise LocalMinimum(grid.cell_to_world(x, y), [grid.cell_to_world(cx, cy) for cx, cy in path])
        x, y = x + int(MOVE_DX[best_k]), y + int(MOVE_DY[best_k])
        path.append((x, y))
    return np.array(path, dtype=np.int64).reshape(-1, 2), examined
