"""Lazy Theta*: any-angle paths on the same blocked grid as A*.

Vertices are cell centres, except that the start cell's vertex is the exact start point and the
goal cell's the exact goal point (both in the continuous cell units of `segment`). The search
expands the 8 neighbours of a cell; a vertex's parent may be any earlier vertex it sees, so the
path's segments take any angle. Every segment, the long line-of-sight shortcuts and the short
steps alike, is checked with `segment.segment_clear` on the blocked grid, so the path touches no
inflated cell: the same footprint rule as A*'s moves and the simplifier.

Lazy (Nash, Koenig and Tovey, 2010): a cell reached from u takes u's parent as its own without a
line-of-sight check; the check runs once, when the cell leaves the open list, and if it fails
the cell falls back to its best closed neighbour (one always sees it: a cell is only generated
from a neighbour whose short step to it is clear). The heuristic is the Euclidean distance to
the goal point (admissible). Theta* is not optimal among any-angle paths, but close: its path
is then pulled taut by `refine_points` (vertices added at the segments' midpoints, each slid
towards the chord of its two neighbours while both segments stay clear) and its corners moved
onto the blocked cells' corners by `snap_to_corners`. Measured against the shortest path that
touches no blocked cell (`visibility.grid_optimum`) on 99 generated arenas (seeds 1 and 2),
the result is that path in 97 (within 0.1 %) and 0.7 % longer at worst, where Theta* chose
another way round an obstacle (benchmarks/bench_anyangle.py).
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import njit
from .astar import _sift_down, _sift_up
from .segment import segment_clear
from .simplify import simplify_points

_TIE_BREAK = 1e-9
_DX8 = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int64)
_DY8 = np.array([0, 1, 1, 1, 0, -1, -1, -1], dtype=np.int64)


@njit
def _vertex(c, nx, start, goal, sx, sy, gx, gy):
    """The point [cells] of cell index c's vertex: its centre, or the exact start / goal."""
    if c == start:
        return sx, sy
    if c == goal:
        return gx, gy
    iy = c // nx
    return c - iy * nx + 0.5, iy + 0.5


@njit
def theta_points(blocked, sx, sy, gx, gy):
    """Search from the point (sx, sy) to the point (gx, gy) [cells] on `blocked` ((ny, nx), [iy, ix]).

    Returns (points, cost, expansions): points an (n, 2) float array of the path's vertices
    [cells], the start and goal points exact; cost its length [cells]; expansions the cells taken
    off the open list. When no path exists, points has no rows and cost is -1. Both end cells
    must be free.
    """
    ny, nx = blocked.shape
    n = nx * ny
    flat = blocked.ravel()
    start = int(math.floor(sy)) * nx + int(math.floor(sx))
    goal = int(math.floor(gy)) * nx + int(math.floor(gx))
    if start == goal:
        out = np.empty((2, 2))
        out[0, 0], out[0, 1], out[1, 0], out[1, 1] = sx, sy, gx, gy
        return out, math.hypot(gx - sx, gy - sy), 0
    g = np.full(n, np.inf)
    key = np.empty(n)
    parent = np.full(n, -1, dtype=np.int64)
    pos = np.full(n, -1, dtype=np.int64)  # index in the heap, -1 not in it, -2 closed
    heap = np.empty(n, dtype=np.int64)
    g[start] = 0.0
    parent[start] = start
    key[start] = math.hypot(gx - sx, gy - sy)
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
        ux, uy = _vertex(u, nx, start, goal, sx, sy, gx, gy)
        p = parent[u]
        if p != u:
            px, py = _vertex(p, nx, start, goal, sx, sy, gx, gy)
            if not segment_clear(blocked, px, py, ux, uy):
                # The lazy guess failed: take the best closed neighbour that sees u.
                best = np.inf
                best_w = -1
                cy = u // nx
                cx = u - cy * nx
                for k in range(8):
                    wx = cx + _DX8[k]
                    wy = cy + _DY8[k]
                    if wx < 0 or wy < 0 or wx >= nx or wy >= ny:
                        continue
                    w = wy * nx + wx
                    if pos[w] != -2 or flat[w]:
                        continue
                    qx, qy = _vertex(w, nx, start, goal, sx, sy, gx, gy)
                    if not segment_clear(blocked, qx, qy, ux, uy):
                        continue
                    c = g[w] + math.hypot(ux - qx, uy - qy)
                    if c < best:
                        best = c
                        best_w = w
                g[u] = best
                parent[u] = best_w
        if u == goal:
            found = True
            break
        p = parent[u]
        px, py = _vertex(p, nx, start, goal, sx, sy, gx, gy)
        gp = g[p]
        cy = u // nx
        cx = u - cy * nx
        for k in range(8):
            vx = cx + _DX8[k]
            vy = cy + _DY8[k]
            if vx < 0 or vy < 0 or vx >= nx or vy >= ny:
                continue
            v = vy * nx + vx
            if pos[v] == -2 or flat[v]:
                continue
            ax, ay = _vertex(v, nx, start, goal, sx, sy, gx, gy)
            if not segment_clear(blocked, ux, uy, ax, ay):
                continue
            gv = gp + math.hypot(ax - px, ay - py)
            if gv < g[v]:
                g[v] = gv
                parent[v] = p
                key[v] = gv * (1.0 - _TIE_BREAK) + math.hypot(gx - ax, gy - ay)
                if pos[v] == -1:
                    heap[size] = v
                    pos[v] = size
                    size += 1
                _sift_up(heap, pos, key, pos[v])
    if not found:
        return np.empty((0, 2)), -1.0, expansions
    length = 1
    c = goal
    while c != start:
        c = parent[c]
        length += 1
    out = np.empty((length, 2))
    c = goal
    for i in range(length - 1, -1, -1):
        out[i, 0], out[i, 1] = _vertex(c, nx, start, goal, sx, sy, gx, gy)
        c = parent[c]
    return out, g[goal], expansions


@njit
def tighten_points(blocked, points, passes=4, steps=12):
    """Slide each interior vertex of a clear polyline [cells] towards its neighbours' chord.

    For a vertex p between a and b, the point q of the chord ab nearest p is where the two
    segments' total length is least, and that total shrinks monotonically as p moves along the
    line to q; so p moves there as far as a bisection (`steps` halvings) finds both segments
    still clear. Every accepted move keeps the polyline clear and never lengthens it; the ends
    stay. `passes` sweeps over the vertices.
    """
    pts = points.copy()
    n = pts.shape[0]
    for _ in range(passes):
        for i in range(1, n - 1):
            ax, ay = pts[i - 1, 0], pts[i - 1, 1]
            bx, by = pts[i + 1, 0], pts[i + 1, 1]
            px, py = pts[i, 0], pts[i, 1]
            dx, dy = bx - ax, by - ay
            dd = dx * dx + dy * dy
            t = 0.0 if dd == 0.0 else ((px - ax) * dx + (py - ay) * dy) / dd
            t = min(max(t, 0.0), 1.0)
            qx, qy = ax + t * dx, ay + t * dy
            lo, hi = 0.0, 1.0
            if segment_clear(blocked, ax, ay, qx, qy) and segment_clear(blocked, qx, qy, bx, by):
                lo = 1.0
            else:
                for _s in range(steps):
                    mid = 0.5 * (lo + hi)
                    mx, my = px + mid * (qx - px), py + mid * (qy - py)
                    if segment_clear(blocked, ax, ay, mx, my) and segment_clear(blocked, mx, my, bx, by):
                        lo = mid
                    else:
                        hi = mid
            if lo > 0.0:
                pts[i, 0] = px + lo * (qx - px)
                pts[i, 1] = py + lo * (qy - py)
    return pts


def refine_points(blocked: np.ndarray, points: np.ndarray, rounds: int = 5, passes: int = 8) -> np.ndarray:
    """Pull a clear polyline [cells] taut round the blocked cells: an elastic band.

    A corner of few vertices cannot hug a rounded obstacle (one vertex standing in for a
    quarter turn of radius ρ adds (2 − π/2)ρ); so each round puts a vertex in the middle of
    every segment, tightens them all (`tighten_points`, `passes` sweeps) and drops the vertices
    the path can skip (`simplify.simplify_points`). Every step keeps the polyline clear and never
    lengthens it; the ends stay.
    """
    pts = simplify_points(blocked, points)
    for _ in range(rounds):
        if len(pts) < 2:
            break
        mids = 0.5 * (pts[:-1] + pts[1:])
        both = np.empty((2 * len(pts) - 1, 2))
        both[0::2] = pts
        both[1::2] = mids
        pts = simplify_points(blocked, tighten_points(blocked, both, passes))
    return pts


_CORNER_OFFSET = 1e-6  # [cells] a snapped vertex sits this far off the blocked cell's corner


@njit
def snap_to_corners(blocked, points, reach=3):
    """Move each interior vertex of a clear polyline [cells] onto a nearby blocked corner where
    that shortens the path and keeps both its segments clear.

    Cells are squares, so the shortest path that touches no blocked cell bends only at convex
    corners of the blocked cells: grid points with exactly one blocked cell of the four around.
    For each vertex, every such corner within `reach` cells (taken `_CORNER_OFFSET` off the
    corner, diagonally away from its blocked cell, as a segment through the very corner touches
    that cell) is tried in its place; the shortest clear choice is kept, and the sweep repeats
    until no vertex moves. The ends stay; the path never lengthens.
    """
    ny, nx = blocked.shape
    pts = points.copy()
    n = pts.shape[0]
    moved = True
    while moved:
        moved = False
        for i in range(1, n - 1):
            ax, ay = pts[i - 1, 0], pts[i - 1, 1]
            bx, by = pts[i + 1, 0], pts[i + 1, 1]
            cx, cy = pts[i, 0], pts[i, 1]
            best = math.hypot(cx - ax, cy - ay) + math.hypot(bx - cx, by - cy)
            best_x, best_y = cx, cy
            gx = int(math.floor(cx + 0.5))
            gy = int(math.floor(cy + 0.5))
            for j in range(max(gy - reach, 1), min(gy + reach + 1, ny)):
                for k in range(max(gx - reach, 1), min(gx + reach + 1, nx)):
                    ll = blocked[j - 1, k - 1]
                    lr = blocked[j - 1, k]
                    ul = blocked[j, k - 1]
                    ur = blocked[j, k]
                    if int(ll) + int(lr) + int(ul) + int(ur) != 1:
                        continue
                    qx = k + (_CORNER_OFFSET if (ll or ul) else -_CORNER_OFFSET)
                    qy = j + (_CORNER_OFFSET if (ll or lr) else -_CORNER_OFFSET)
                    length = math.hypot(qx - ax, qy - ay) + math.hypot(bx - qx, by - qy)
                    if length < best - 1e-12:
                        if segment_clear(blocked, ax, ay, qx, qy) and segment_clear(blocked, qx, qy, bx, by):
                            best = length
                            best_x, best_y = qx, qy
            if best_x != cx or best_y != cy:
                pts[i, 0] = best_x
                pts[i, 1] = best_y
                moved = True
    return pts
