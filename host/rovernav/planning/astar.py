"""A* over the occupancy grid with the seed's 16-direction motion model.

The search is optimal on its grid: the heuristic is the exact 16-direction distance over an
empty grid (`moves.free_space_distance`), which is admissible and consistent, so a cell is
final when it leaves the open list. Ties in f are broken towards the deeper cell (key
f − 1e-9·g), which keeps the search on a straight front across open floor; the cost this
can add is below 1e-9 of the path's length.

Speed: the loop runs compiled (numba, see `_jit`) over flat arrays with an indexed binary
heap (decrease-key, at most one entry per cell), checks each move's cells on the fly, and
stops as soon as the goal leaves the open list. Measured in `benchmarks/bench_planning.py`.
"""

from __future__ import annotations

import numpy as np

from ._jit import njit
from .moves import MID1_DX, MID1_DY, MID2_DX, MID2_DY, MOVE_COST, MOVE_DX, MOVE_DY, N_MOVES, SQRT2, SQRT5

_TIE_BREAK = 1e-9


@njit
def _heuristic(x, y, gx, gy):
    ax = abs(x - gx)
    ay = abs(y - gy)
    if ay > ax:
        ax, ay = ay, ax
    if 2 * ay <= ax:
        return ay * SQRT5 + (ax - 2 * ay)
    return (ax - ay) * SQRT5 + (2 * ay - ax) * SQRT2


@njit
def _sift_up(heap, pos, key, i):
    node = heap[i]
    k = key[node]
    while i > 0:
        parent = (i - 1) >> 1
        pnode = heap[parent]
        if key[pnode] <= k:
            break
        heap[i] = pnode
        pos[pnode] = i
        i = parent
    heap[i] = node
    pos[node] = i


@njit
def _sift_down(heap, pos, key, i, size):
    node = heap[i]
    k = key[node]
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and key[heap[right]] < key[heap[child]]:
            child = right
        cnode = heap[child]
        if key[cnode] >= k:
            break
        heap[i] = cnode
        pos[cnode] = i
        i = child
    heap[i] = node
    pos[node] = i


@njit
def astar_cells(blocked, sx, sy, gx, gy):
    """Search from cell (sx, sy) to cell (gx, gy) on `blocked` (a (ny, nx) bool array, [iy, ix]).

    Returns (path, cost, expansions): path an (n, 2) int64 array of (ix, iy) from start to goal,
    cost its length in cells, expansions the number of cells taken off the open list. When no
    path exists, path has no rows and cost is -1. Both end cells must be free.
    """
    ny, nx = blocked.shape
    n = nx * ny
    flat = blocked.ravel()
    g = np.full(n, np.inf)
    key = np.empty(n)
    parent = np.full(n, -1, dtype=np.int64)
    pos = np.full(n, -1, dtype=np.int64)  # index in the heap, -1 not in it, -2 closed
    heap = np.empty(n, dtype=np.int64)
    start = sy * nx + sx
    goal = gy * nx + gx
    g[start] = 0.0
    key[start] = _heuristic(sx, sy, gx, gy)
    heap[0] = start
    pos[start] = 0
    size = 1
    expansions = 0
    found = False
    while size > 0:
        u = heap[0]
        size -= 1
        pos[u] = -2
        if size > 0:
            heap[0] = heap[size]
            pos[heap[0]] = 0
            _sift_down(heap, pos, key, 0, size)
        expansions += 1
        if u == goal:
            found = True
            break
        uy = u // nx
        ux = u - uy * nx
        gu = g[u]
        for k in range(N_MOVES):
            vx = ux + MOVE_DX[k]
            vy = uy + MOVE_DY[k]
            if vx < 0 or vy < 0 or vx >= nx or vy >= ny:
                continue
            v = vy * nx + vx
            if pos[v] == -2 or flat[v]:
                continue
            if blocked[uy + MID1_DY[k], ux + MID1_DX[k]] or blocked[uy + MID2_DY[k], ux + MID2_DX[k]]:
                continue
            gv = gu + MOVE_COST[k]
            if gv < g[v]:
                g[v] = gv
                parent[v] = u
                key[v] = gv * (1.0 - _TIE_BREAK) + _heuristic(vx, vy, gx, gy)
                if pos[v] == -1:
                    heap[size] = v
                    pos[v] = size
                    size += 1
                _sift_up(heap, pos, key, pos[v])
    if not found:
        return np.empty((0, 2), dtype=np.int64), -1.0, expansions
    length = 1
    c = goal
    while c != start:
        c = parent[c]
        length += 1
    path = np.empty((length, 2), dtype=np.int64)
    c = goal
    for i in range(length - 1, -1, -1):
        path[i, 0] = c % nx
        path[i, 1] = c // nx
        c = parent[c]
    return path, g[goal], expansions


def path_cost(path: np.ndarray) -> float:
    """Length [cells] of a cell path: the sum of its steps' Euclidean lengths."""
    if len(path) < 2:
        return 0.0
    steps = np.diff(np.asarray(path, dtype=np.float64), axis=0)
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum())
