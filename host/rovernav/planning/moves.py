"""The seed's 16-direction motion model: 8 neighbours and 8 knight moves.

Costs are the Euclidean lengths in cells: 1, √2 and √5. A move is allowed when every cell its
segment (cell centre to cell centre) touches is free:

- a straight move touches only its two end cells;
- a diagonal passes exactly through the corner shared by its two side cells, so both side
  cells must be free too (no cutting a corner of an obstacle);
- a knight move (2, 1) crosses two more cells: (1, 0) and (1, 1) from the start, and
  likewise for the other seven by symmetry.

`MID1_*` and `MID2_*` name those extra cells (a straight move repeats its start cell, which
is free anyway). `segment.segment_clear` gives the same answer for every move, so a
simplified path obeys the very rule the search did.
"""

from __future__ import annotations

import math

import numpy as np

SQRT2 = math.sqrt(2.0)
SQRT5 = math.sqrt(5.0)


def _mids(dx: int, dy: int) -> tuple[tuple[int, int], tuple[int, int]]:
    if abs(dx) + abs(dy) == 1:
        return (0, 0), (0, 0)
    if abs(dx) == 1 and abs(dy) == 1:
        return (dx, 0), (0, dy)
    if abs(dx) == 2:
        return (dx // 2, 0), (dx // 2, dy)
    return (0, dy // 2), (dx, dy // 2)


_MOVES = [
    (1, 0),
    (0, 1),
    (-1, 0),
    (0, -1),
    (1, 1),
    (-1, 1),
    (-1, -1),
    (1, -1),
    (2, 1),
    (1, 2),
    (-1, 2),
    (-2, 1),
    (-2, -1),
    (-1, -2),
    (1, -2),
    (2, -1),
]

MOVE_DX = np.array([m[0] for m in _MOVES], dtype=np.int64)
MOVE_DY = np.array([m[1] for m in _MOVES], dtype=np.int64)
MOVE_COST = np.array([math.hypot(*m) for m in _MOVES], dtype=np.float64)
MID1_DX = np.array([_mids(*m)[0][0] for m in _MOVES], dtype=np.int64)
MID1_DY = np.array([_mids(*m)[0][1] for m in _MOVES], dtype=np.int64)
MID2_DX = np.array([_mids(*m)[1][0] for m in _MOVES], dtype=np.int64)
MID2_DY = np.array([_mids(*m)[1][1] for m in _MOVES], dtype=np.int64)
N_MOVES = len(_MOVES)
N_NEIGHBOURS_8 = 8  # the first eight moves are the 8-neighbourhood


def free_space_distance(dx: float, dy: float) -> float:
    """Length [cells] of the shortest 16-direction path over an empty grid from (0, 0) to (dx, dy).

    With |dx| ≥ |dy| (swap otherwise): up to a slope of 1/2 the path mixes knight moves and
    straight moves, beyond it knight moves and diagonals. It is the exact distance of the
    motion model without obstacles, so as an A* heuristic it is admissible and consistent,
    and tighter than the Euclidean distance.
    """
    ax, ay = abs(dx), abs(dy)
    if ay > ax:
        ax, ay = ay, ax
    if 2.0 * ay <= ax:
        return ay * SQRT5 + (ax - 2.0 * ay)
    return (ax - ay) * SQRT5 + (2.0 * ay - ax) * SQRT2


def move_allowed(blocked: np.ndarray, ix: int, iy: int, k: int) -> bool:
    """Whether move `k` from free cell (ix, iy) stays on the grid and touches only free cells."""
    ny, nx = blocked.shape
    jx, jy = ix + int(MOVE_DX[k]), iy + int(MOVE_DY[k])
    if not (0 <= jx < nx and 0 <= jy < ny) or blocked[jy, jx]:
        return False
    return not (blocked[iy + MID1_DY[k], ix + MID1_DX[k]] or blocked[iy + MID2_DY[k], ix + MID2_DX[k]])
