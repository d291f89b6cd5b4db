"""Drop the waypoints the rover can skip in a straight line.

The seed's rover stopped and turned at every grid cell of its path. Here, from each kept
waypoint the path jumps to the last point it can still see — the farthest point before the
first one whose segment fails `segment.segment_clear` on the inflated grid — so every kept
segment obeys the same conservative rule as the search, the start and the goal are kept, and
the result is never longer than the input (each jump replaces a chain by its chord).
"""

from __future__ import annotations

import numpy as np

from ._jit import njit
from .segment import segment_clear


@njit
def _keep_indices(blocked, points):
    n = points.shape[0]
    keep = np.empty(n, dtype=np.int64)
    count = 0
    keep[count] = 0
    count += 1
    anchor = 0
    while anchor < n - 1:
        last = anchor + 1
        j = anchor + 2
        while j < n and segment_clear(blocked, points[anchor, 0], points[anchor, 1], points[j, 0], points[j, 1]):
            last = j
            j += 1
        keep[count] = last
        count += 1
        anchor = last
    return keep[:count]


def simplify_points(blocked: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The points [cells] of a clear polyline, with every waypoint it can skip removed.

    `points` is an (n, 2) float array in cell units (see `segment`); the first and last points
    are always kept. Consecutive duplicate points are dropped first.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) > 1:
        same = np.all(pts[1:] == pts[:-1], axis=1)
        pts = np.concatenate([pts[:1], pts[1:][~same]])
    if len(pts) <= 2:
        return pts
    return pts[_keep_indices(blocked, pts)]
