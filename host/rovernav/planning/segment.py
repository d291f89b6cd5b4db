"""The one segment check used by the search, the simplifier and `OccupancyGrid.path_blocked`.

Coordinates here are in cells: cell (ix, iy) is the square [ix, ix+1) × [iy, iy+1), so a cell
centre is (ix + 0.5, iy + 0.5). A segment is clear when every cell its closed segment touches
is free: a walk from cell to cell along the segment (Amanatides and Woo's traversal), and
where the segment passes through a grid corner (within 1e-9 of the segment's length) both
cells beside that corner count as touched. This is the supercover of the segment; for the
16 moves of `moves` it touches exactly the cells `moves.move_allowed` checks.
"""

from __future__ import annotations

import math

from ._jit import njit

_CORNER_TOL = 1e-9


@njit
def segment_clear(blocked, x0, y0, x1, y1):
    """True when the segment (x0, y0)–(x1, y1) [cells] touches no blocked cell and stays on the grid."""
    ny, nx = blocked.shape
    ix = int(math.floor(x0))
    iy = int(math.floor(y0))
    jx = int(math.floor(x1))
    jy = int(math.floor(y1))
    if ix < 0 or iy < 0 or ix >= nx or iy >= ny or jx < 0 or jy < 0 or jx >= nx or jy >= ny:
        return False
    if blocked[iy, ix]:
        return False
    dx = x1 - x0
    dy = y1 - y0
    inf = math.inf
    if dx > 0.0:
        step_x = 1
        t_delta_x = 1.0 / dx
        t_max_x = (ix + 1 - x0) / dx
    elif dx < 0.0:
        step_x = -1
        t_delta_x = -1.0 / dx
        t_max_x = (x0 - ix) / -dx
    else:
        step_x = 0
        t_delta_x = inf
        t_max_x = inf
    if dy > 0.0:
        step_y = 1
        t_delta_y = 1.0 / dy
        t_max_y = (iy + 1 - y0) / dy
    elif dy < 0.0:
        step_y = -1
        t_delta_y = -1.0 / dy
        t_max_y = (y0 - iy) / -dy
    else:
        step_y = 0
        t_delta_y = inf
        t_max_y = inf
    remaining = abs(jx - ix) + abs(jy - iy)
    while remaining > 0:
        if ix != jx and iy != jy and abs(t_max_x - t_max_y) <= _CORNER_TOL:
            # Through a grid corner: the two cells beside it are touched too.
            if blocked[iy, ix + step_x] or blocked[iy + step_y, ix]:
                return False
            ix += step_x
            iy += step_y
            t_max_x += t_delta_x
            t_max_y += t_delta_y
            remaining -= 2
        elif (t_max_x < t_max_y and ix != jx) or iy == jy:
            ix += step_x
            t_max_x += t_delta_x
            remaining -= 1
        else:
            iy += step_y
            t_max_y += t_delta_y
            remaining -= 1
        if ix < 0 or iy < 0 or ix >= nx or iy >= ny:
            return False
        if blocked[iy, ix]:
            return False
    return True


@njit
def polyline_clear(blocked, points):
    """True when every segment of `points` (an (n, 2) float array [cells]) is clear."""
    n = points.shape[0]
    if n == 1:
        return segment_clear(blocked, points[0, 0], points[0, 1], points[0, 0], points[0, 1])
    for i in range(n - 1):
        if not segment_clear(blocked, points[i, 0], points[i, 1], points[i + 1, 0], points[i + 1, 1]):
            return False
    return True
