"""The shortest path among the inflated obstacles, by a visibility graph: a yardstick for benchmarks
and tests (the mission never uses it).

With every obstacle known, the shortest path of a point rover that keeps its centre
`inflation_m` from every obstacle and from the arena's wall is a polyline whose corners lie on
the inflated obstacles' boundaries. Here each inflated obstacle is a convex polygon:

- a box or a wall (a rectangle) grown by r is a rounded rectangle; each rounded corner is
  replaced by a regular polygon's arc with `sides_per_circle` sides per full turn (32 by
  default), circumscribed about the arc (its vertices at r / cos(π/N) from the corner, its edges
  tangent to the circle, the straight sides exactly at r);
- a post of radius R grown by r is a disk of radius R + r, replaced by the circumscribed
  regular N-gon.

Circumscribed polygons contain the true inflated region, so every path found here is feasible
for the true geometry, and its length is at least the true optimum. The excess is small: each
polygon lies within r' = r / cos(π/N) of its obstacle, and growing convex obstacles from r to r'
lengthens a taut path by at most (r' − r) per radian it turns round them, 3.3 mm per radian for
r = 0.17 m and N = 32. `inscribed=True` builds the polygons inside the region instead (vertices
at r, edges at r cos(π/N)): that path may cut into the true region by up to r (1 − cos(π/N))
(also 3.3 mm) and its length is at most the optimum, so the two results bracket it.

Nodes: the polygons' vertices that lie in the free space (inside the arena shrunk by r, outside
every other polygon), the start and the goal. Edges: pairs whose segment crosses no polygon's
interior (touching an edge or a vertex is allowed); the shrunk arena is convex, so a segment
between two nodes in it stays in it. Dijkstra (scipy.sparse.csgraph) gives the optimum.

`grid_optimum` is the same construction on the grid itself: the shortest path that touches no
blocked cell, the best any planner using `segment.segment_clear` can do at that resolution.
The benchmark (benchmarks/bench_anyangle.py) sets a planner's path against both.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ._jit import njit
from .segment import segment_clear

_EPS = 1e-9


@dataclasses.dataclass(frozen=True)
class VisibilityResult:
    """length_m: the shortest path's length [m] (inf when start and goal are not joined);
    waypoints: its corners [m], start to goal; nodes, edges: the graph's size."""

    length_m: float
    waypoints: tuple[tuple[float, float], ...]
    nodes: int
    edges: int


def _corner_arc(n_sides: int, radius: float, inscribed: bool) -> np.ndarray:
    """Offsets of a regular n-gon's vertices about a centre: circumscribed about the circle of
    `radius` (edges tangent, one edge normal along each axis) or inscribed in it."""
    if inscribed:
        angles = 2 * math.pi * np.arange(n_sides) / n_sides
        r = radius
    else:
        angles = 2 * math.pi * (np.arange(n_sides) + 0.5) / n_sides
        r = radius / math.cos(math.pi / n_sides)
    return r * np.column_stack([np.cos(angles), np.sin(angles)])


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (Andrew's monotone chain), collinear points dropped."""
    pts = sorted(set(map(tuple, np.round(points, 12))))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def inflated_polygons(
    boxes: Sequence[tuple[float, float, float, float]],
    walls: Sequence[tuple[float, float, float, float, float]],
    posts: Sequence[tuple[float, float, float]],
    inflation_m: float,
    sides_per_circle: int = 32,
    inscribed: bool = False,
) -> list[np.ndarray]:
    """Each obstacle grown by `inflation_m`, as a counter-clockwise convex polygon [m].

    boxes (x, y, w, h): centre and size; walls (x0, y0, x1, y1, thickness); posts (x, y, radius).
    """
    if sides_per_circle < 4 or sides_per_circle % 4:
        raise ValueError(f"sides_per_circle must be a positive multiple of 4, got {sides_per_circle!r}")
    polys = []
    arc = _corner_arc(sides_per_circle, inflation_m, inscribed) if inflation_m > 0 else np.zeros((1, 2))
    for x, y, w, h in boxes:
        corners = np.array(
            [[x - w / 2, y - h / 2], [x + w / 2, y - h / 2], [x + w / 2, y + h / 2], [x - w / 2, y + h / 2]]
        )
        polys.append(_convex_hull((corners[:, None, :] + arc[None, :, :]).reshape(-1, 2)))
    for x0, y0, x1, y1, t in walls:
        length = math.hypot(x1 - x0, y1 - y0)
        ux, uy = (x1 - x0) / length, (y1 - y0) / length
        nx_, ny_ = -uy * t / 2, ux * t / 2
        corners = np.array([[x0 + nx_, y0 + ny_], [x1 + nx_, y1 + ny_], [x1 - nx_, y1 - ny_], [x0 - nx_, y0 - ny_]])
        if inflation_m > 0:
            # The arc's polygon turned to the wall's frame, so its straight sides sit exactly at r.
            c, s = ux, uy
            turned = arc @ np.array([[c, s], [-s, c]])
        else:
            turned = arc
        polys.append(_convex_hull((corners[:, None, :] + turned[None, :, :]).reshape(-1, 2)))
    for x, y, r in posts:
        polys.append(_convex_hull(np.array([x, y]) + _corner_arc(sides_per_circle, r + inflation_m, inscribed)))
    return polys


@njit
def _crosses_interior(ax, ay, bx, by, edges_n, edges_c, poly_start, poly_end, bbox):
    """Whether the segment a-b enters the interior of any polygon (Cyrus-Beck clipping against
    each polygon's half-planes n·x < c; a touch, of length or depth ≤ 1e-9, does not count)."""
    lo_x, hi_x = min(ax, bx), max(ax, bx)
    lo_y, hi_y = min(ay, by), max(ay, by)
    dx, dy = bx - ax, by - ay
    for p in range(poly_start.shape[0]):
        if hi_x <= bbox[p, 0] or lo_x >= bbox[p, 2] or hi_y <= bbox[p, 1] or lo_y >= bbox[p, 3]:
            continue
        t0, t1 = 0.0, 1.0
        inside = True
        for e in range(poly_start[p], poly_end[p]):
            nxe, nye, c = edges_n[e, 0], edges_n[e, 1], edges_c[e] - 1e-9
            num = c - (nxe * ax + nye * ay)  # a is strictly inside this half-plane when num > 0
            den = nxe * dx + nye * dy
            if den == 0.0:
                if num <= 0.0:
                    inside = False
                    break
            elif den > 0.0:
                t1 = min(t1, num / den)
            else:
                t0 = max(t0, num / den)
            if t1 - t0 <= 1e-9:
                inside = False
                break
        if inside:
            return True
    return False


@njit
def _point_inside(x, y, edges_n, edges_c, poly_start, poly_end):
    for p in range(poly_start.shape[0]):
        inside = True
        for e in range(poly_start[p], poly_end[p]):
            if edges_n[e, 0] * x + edges_n[e, 1] * y >= edges_c[e] - 1e-9:
                inside = False
                break
        if inside:
            return True
    return False


@njit
def _edges(nodes, edges_n, edges_c, poly_start, poly_end, bbox):
    n = nodes.shape[0]
    src = np.empty(n * (n - 1) // 2, dtype=np.int64)
    dst = np.empty(n * (n - 1) // 2, dtype=np.int64)
    count = 0
    for i in range(n):
        for j in range(i + 1, n):
            if not _crosses_interior(
                nodes[i, 0], nodes[i, 1], nodes[j, 0], nodes[j, 1], edges_n, edges_c, poly_start, poly_end, bbox
            ):
                src[count] = i
                dst[count] = j
                count += 1
    return src[:count], dst[:count]


def shortest_path(
    polygons: Sequence[np.ndarray],
    start_xy: Sequence[float],
    goal_xy: Sequence[float],
    width_m: float,
    height_m: float,
    inflation_m: float,
) -> VisibilityResult:
    """The shortest path [m] from start to goal that enters no polygon's interior and stays in the
    arena shrunk by `inflation_m` (see the module's notes). Start and goal must be free."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    r = inflation_m
    normals, offsets, starts, ends, boxes = [], [], [], [], []
    count = 0
    for poly in polygons:
        a = np.asarray(poly, dtype=np.float64)
        b = np.roll(a, -1, axis=0)
        d = b - a
        n = np.column_stack([d[:, 1], -d[:, 0]])  # outward for a counter-clockwise polygon
        n /= np.hypot(n[:, 0], n[:, 1])[:, None]
        normals.append(n)
        offsets.append((n * a).sum(axis=1))
        starts.append(count)
        count += len(a)
        ends.append(count)
        boxes.append([a[:, 0].min(), a[:, 1].min(), a[:, 0].max(), a[:, 1].max()])
    edges_n = np.concatenate(normals) if normals else np.zeros((0, 2))
    edges_c = np.concatenate(offsets) if offsets else np.zeros(0)
    poly_start = np.array(starts, dtype=np.int64)
    poly_end = np.array(ends, dtype=np.int64)
    bbox = np.array(boxes, dtype=np.float64).reshape(-1, 4)

    candidates = [np.asarray(start_xy, dtype=np.float64), np.asarray(goal_xy, dtype=np.float64)]
    for poly in polygons:
        candidates.extend(np.asarray(poly, dtype=np.float64))
    nodes = [candidates[0], candidates[1]]
    for p in candidates[2:]:
        if not (r - _EPS <= p[0] <= width_m - r + _EPS and r - _EPS <= p[1] <= height_m - r + _EPS):
            continue
        if _point_inside(p[0], p[1], edges_n, edges_c, poly_start, poly_end):
            continue
        nodes.append(p)
    pts = np.array(nodes)
    src, dst = _edges(pts, edges_n, edges_c, poly_start, poly_end, bbox)
    w = np.hypot(*(pts[dst] - pts[src]).T)
    keep = w > 0
    graph = coo_matrix((w[keep], (src[keep], dst[keep])), shape=(len(pts), len(pts))).tocsr()
    dist, pred = dijkstra(graph, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return VisibilityResult(math.inf, (), len(pts), int(keep.sum()))
    path = [1]
    while path[-1] != 0:
        path.append(int(pred[path[-1]]))
    waypoints = tuple((float(pts[i, 0]), float(pts[i, 1])) for i in reversed(path))
    return VisibilityResult(float(dist[1]), waypoints, len(pts), int(keep.sum()))


def scenario_optimum(
    scenario, inflation_m: float, sides_per_circle: int = 32, inscribed: bool = False
) -> VisibilityResult:
    """The visibility-graph optimum of a scenario with every obstacle (boxes, walls, posts) known."""
    boxes = [(o.x_m, o.y_m, o.w_m, o.h_m) for o in scenario.obstacles]
    walls = [(w.x0_m, w.y0_m, w.x1_m, w.y1_m, w.thickness_m) for w in getattr(scenario, "walls", ())]
    posts = [(p.x_m, p.y_m, p.radius_m) for p in getattr(scenario, "posts", ())]
    polys = inflated_polygons(boxes, walls, posts, inflation_m, sides_per_circle, inscribed)
    return shortest_path(
        polys, scenario.start.xy, scenario.target.xy, scenario.arena.width_m, scenario.arena.height_m, inflation_m
    )


@njit
def _clear_pairs(blocked, pts):
    n = pts.shape[0]
    src = np.empty(n * (n - 1) // 2, dtype=np.int64)
    dst = np.empty(n * (n - 1) // 2, dtype=np.int64)
    count = 0
    for i in range(n):
        for j in range(i + 1, n):
            if segment_clear(blocked, pts[i, 0], pts[i, 1], pts[j, 0], pts[j, 1]):
                src[count] = i
                dst[count] = j
                count += 1
    return src[:count], dst[:count]


def grid_optimum(blocked: np.ndarray, start_cells: Sequence[float], goal_cells: Sequence[float]) -> float:
    """The shortest path [cells] between two points [cells] that touches no blocked cell (by
    `segment.segment_clear`): the best any planner using that check can do on this grid.

    The blocked cells form rectilinear polygons, so the shortest path bends only at their convex
    corners: grid points where exactly one of the four cells around is blocked. Each is taken
    1e-7 cells off the corner, diagonally away from its blocked cell (a segment through the very
    corner touches the cell), and joined to every node it sees; Dijkstra gives the length (inf
    when there is no path). O(corners²) segment checks: for benchmarks and tests.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    b = np.asarray(blocked, dtype=bool)
    ny, nx = b.shape
    # Cells round the interior grid point (i, j): lower-left b[j-1, i-1], lower-right b[j-1, i],
    # upper-left b[j, i-1], upper-right b[j, i].
    ll, lr, ul, ur = b[:-1, :-1], b[:-1, 1:], b[1:, :-1], b[1:, 1:]
    one = (ll.astype(int) + lr + ul + ur) == 1
    jj, ii = np.nonzero(one)
    x = ii + 1.0
    y = jj + 1.0
    off = 1e-7
    # Away from the blocked cell: right when it is on the left, up when it is below.
    x += np.where(ll[one] | ul[one], off, -off)
    y += np.where(ll[one] | lr[one], off, -off)
    pts = np.concatenate([[start_cells, goal_cells], np.column_stack([x, y])]).astype(np.float64)
    src, dst = _clear_pairs(b, pts)
    w = np.hypot(*(pts[dst] - pts[src]).T)
    graph = coo_matrix((w, (src, dst)), shape=(len(pts), len(pts))).tocsr()
    return float(dijkstra(graph, directed=False, indices=0)[1])
