"""The arena as an occupancy grid: a raw obstacle layer and the inflated layer the planner avoids.

Cells and coordinates
    Metres, origin at the arena's bottom-left corner, x right, y up. Cell (ix, iy) covers
    [ix·res, (ix+1)·res) × [iy·res, (iy+1)·res); its centre, where a path's waypoints sit, is
    ((ix + 0.5)·res, (iy + 0.5)·res). Arrays are indexed [iy, ix], row 0 at the bottom (flip
    them to draw an image). The last column and row may reach past the arena's edge.

Obstacles and layers
    Obstacles are kept as geometry: axis-aligned boxes (centre, size), walls (oriented
    rectangles: a segment with a thickness, square ends flush with its end points; a wall along
    x or y is kept as the box it is), posts (disks of any radius) and small disks (the points a
    sonar echo's arc is sampled at, each with a radius covering the arc between samples). From
    them:
    `raw`: the cells a box, a wall or a post overlaps (with some area, not only an edge) or a
    sonar disk's centre lies in (what an obstacle occupies).
    `inflated`: the cells the rover's centre must not enter: those whose centre lies within
    `config.inflation_m` (robot radius + sonar margin) of an obstacle, or of the arena's
    wall. The distance is exact (the seed's rule: a cell centre within the robot radius of
    an obstacle), computed per obstacle in a window around it, so a gap the rover fits
    through is not closed by rounding to cells, and a new obstacle re-inflates only its window
    (a box's window with a compiled loop, `_grow_box`, the same float operations as numpy's).
    (A disk dilation of the raw cells rounds each obstacle out by up to a cell, 0.03 m, and
    measured no faster: 0.06 to 0.1 ms for the seed's arena, 0.8 ms for 40 boxes on 400 × 400.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..validate import check_grid
from ._jit import njit
from .config import PlannerConfig
from .segment import polyline_clear, segment_clear

if TYPE_CHECKING:  # pragma: no cover
    from ..scenario import Scenario


@njit
def _grow_box(inflated, xs, ys, x, y, half_w, half_h, limit, r0, r1, c0, c1):
    """Block the cells of rows r0:r1, columns c0:c1 whose centre lies within `limit` [m] of the
    box (centre x, y, half sizes [m]); returns how many were free. The same float operations as
    `_box_distance` and `_grow` with numpy, so the same cells."""
    newly = 0
    for r in range(r0, r1):
        dy = max(abs(ys[r] - y) - half_h, 0.0)
        dy2 = dy * dy
        row = inflated[r]
        for c in range(c0, c1):
            dx = max(abs(xs[c] - x) - half_w, 0.0)
            if math.sqrt(dx * dx + dy2) <= limit and not row[c]:
                row[c] = True
                newly += 1
    return newly


class OccupancyGrid:
    """An arena of `width_m` × `height_m` metres, cut into square cells of `config.resolution_m`."""

    def __init__(self, width_m: float, height_m: float, config: PlannerConfig | None = None):
        if not (width_m > 0 and height_m > 0 and math.isfinite(width_m) and math.isfinite(height_m)):
            raise ValueError(f"arena size must be positive, got {width_m!r} × {height_m!r} m")
        self.config = config or PlannerConfig()
        check_grid(width_m, height_m, self.config.resolution_m)  # before any array is allocated
        self.width_m = float(width_m)
        self.height_m = float(height_m)
        self.resolution_m = self.config.resolution_m
        res = self.resolution_m
        self.nx = max(1, int(math.ceil(self.width_m / res - 1e-9)))
        self.ny = max(1, int(math.ceil(self.height_m / res - 1e-9)))
        self.xs = (np.arange(self.nx) + 0.5) * res  # cell-centre x [m] of each column
        self.ys = (np.arange(self.ny) + 0.5) * res  # cell-centre y [m] of each row
        self.boxes: list[tuple[float, float, float, float]] = []  # (x, y, w, h) [m]
        # Oblique walls: (centre x, centre y, unit vector along x, y, half length, half thickness) [m]
        self.walls: list[tuple[float, float, float, float, float, float]] = []
        self.posts: list[tuple[float, float, float]] = []  # (x, y, radius) [m]
        self.disks: list[np.ndarray] = []  # groups of disks, each an (n, 3) array of (x, y, radius) [m]
        self.raw = np.zeros((self.ny, self.nx), dtype=np.bool_)
        self.inflated = self.wall_band(self.config.inflation_m)
        self.geometric = True  # the layers follow from boxes and disks (False: given by from_layers)
        self.version = 0  # bumped whenever a layer changes

    # --- construction --------------------------------------------------------------------

    @classmethod
    def from_scenario(
        cls, scenario: Scenario, config: PlannerConfig | None = None, all_obstacles: bool = False
    ) -> OccupancyGrid:
        """The scenario's arena with its known obstacles (all of them when `all_obstacles`)."""
        grid = cls(scenario.arena.width_m, scenario.arena.height_m, config)
        for o in scenario.obstacles:
            if all_obstacles or o.known:
                grid.add_box(o.x_m, o.y_m, o.w_m, o.h_m)
        for w in getattr(scenario, "walls", ()):
            if all_obstacles or w.known:
                grid.add_wall(w.x0_m, w.y0_m, w.x1_m, w.y1_m, w.thickness_m)
        for p in getattr(scenario, "posts", ()):
            if all_obstacles or p.known:
                grid.add_post(p.x_m, p.y_m, p.radius_m)
        return grid

    @classmethod
    def from_layers(
        cls, inflated: np.ndarray, resolution_m: float = 1.0, raw: np.ndarray | None = None
    ) -> OccupancyGrid:
        """A grid whose inflated layer is given as is (no geometry, no wall band): for tests and tools."""
        inflated = np.ascontiguousarray(inflated, dtype=np.bool_)
        ny, nx = inflated.shape
        grid = cls(
            nx * resolution_m,
            ny * resolution_m,
            PlannerConfig(resolution_m=resolution_m, robot_radius_m=0.0, sonar_margin_m=0.0),
        )
        grid.inflated = inflated.copy()
        grid.geometric = False
        grid.raw = inflated.copy() if raw is None else np.ascontiguousarray(raw, dtype=np.bool_).copy()
        return grid

    def copy(self) -> OccupancyGrid:
        other = object.__new__(OccupancyGrid)
        other.__dict__.update(self.__dict__)
        other.raw = self.raw.copy()
        other.inflated = self.inflated.copy()
        other.boxes = list(self.boxes)
        other.walls = list(self.walls)
        other.posts = list(self.posts)
        other.disks = list(self.disks)
        return other

    # --- coordinates ---------------------------------------------------------------------

    def contains(self, x_m: float, y_m: float) -> bool:
        """Whether (x, y) [m] lies on the arena (its edges included)."""
        return 0.0 <= x_m <= self.width_m and 0.0 <= y_m <= self.height_m

    def world_to_cell(self, x_m: float, y_m: float) -> tuple[int, int]:
        """The cell (ix, iy) holding the point (x, y) [m]; a point on the far edges maps to the last cell."""
        res = self.resolution_m
        return (min(int(math.floor(x_m / res)), self.nx - 1), min(int(math.floor(y_m / res)), self.ny - 1))

    def cell_to_world(self, ix: int, iy: int) -> tuple[float, float]:
        """The centre [m] of cell (ix, iy)."""
        res = self.resolution_m
        return ((ix + 0.5) * res, (iy + 0.5) * res)

    def cells_to_world(self, cells: np.ndarray) -> np.ndarray:
        """Centres [m] of an (n, 2) array of cells (ix, iy)."""
        return (np.asarray(cells, dtype=np.float64).reshape(-1, 2) + 0.5) * self.resolution_m

    def to_cell_units(self, points_m: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
        """Points [m] → the continuous cell coordinates of the segment check (cell (i, j) is [i, i+1) × [j, j+1))."""
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2) / self.resolution_m
        # A point on the arena's far edge belongs to the last cell, as in world_to_cell.
        np.minimum(pts[:, 0], np.nextafter(self.nx, 0), out=pts[:, 0])
        np.minimum(pts[:, 1], np.nextafter(self.ny, 0), out=pts[:, 1])
        return pts

    def is_free(self, x_m: float, y_m: float) -> bool:
        """Whether the rover's centre may stand at (x, y) [m]."""
        if not self.contains(x_m, y_m):
            return False
        ix, iy = self.world_to_cell(x_m, y_m)
        return not self.inflated[iy, ix]

    # --- distances -----------------------------------------------------------------------

    def _window(self, x0: float, y0: float, x1: float, y1: float, margin: float) -> tuple[slice, slice]:
        """The cells whose centre lies in [x0 − margin, x1 + margin] × [y0 − margin, y1 + margin]."""
        res = self.resolution_m
        c0 = max(int(math.floor((x0 - margin) / res - 0.5)), 0)
        c1 = min(int(math.ceil((x1 + margin) / res - 0.5)) + 1, self.nx)
        r0 = max(int(math.floor((y0 - margin) / res - 0.5)), 0)
        r1 = min(int(math.ceil((y1 + margin) / res - 0.5)) + 1, self.ny)
        return slice(r0, max(r1, r0)), slice(c0, max(c1, c0))

    def _box_distance(
        self, box: tuple[float, float, float, float], reach: float
    ) -> tuple[tuple[slice, slice], np.ndarray]:
        x, y, w, h = box
        rows, cols = self._window(x - w / 2, y - h / 2, x + w / 2, y + h / 2, reach)
        dx = np.maximum(np.abs(self.xs[cols] - x) - w / 2, 0.0)
        dy = np.maximum(np.abs(self.ys[rows] - y) - h / 2, 0.0)
        return (rows, cols), np.sqrt(dx[None, :] ** 2 + dy[:, None] ** 2)

    def _wall_local(
        self, wall: tuple[float, float, float, float, float, float], reach: float
    ) -> tuple[tuple[slice, slice], np.ndarray, np.ndarray]:
        """The window of cells round an oblique wall and their centres in the wall's frame:
        (window, |along| [m], |across| [m])."""
        cx, cy, ux, uy, a, b = wall
        ex, ey = abs(ux) * a + abs(uy) * b, abs(uy) * a + abs(ux) * b  # half extents of the bounding box
        rows, cols = self._window(cx - ex, cy - ey, cx + ex, cy + ey, reach)
        dx = self.xs[cols][None, :] - cx
        dy = self.ys[rows][:, None] - cy
        return (rows, cols), np.abs(dx * ux + dy * uy), np.abs(dy * ux - dx * uy)

    def _wall_distance(
        self, wall: tuple[float, float, float, float, float, float], reach: float
    ) -> tuple[tuple[slice, slice], np.ndarray]:
        window, along, across = self._wall_local(wall, reach)
        a, b = wall[4], wall[5]
        return window, np.hypot(np.maximum(along - a, 0.0), np.maximum(across - b, 0.0))

    def _post_distance(self, post: tuple[float, float, float], reach: float) -> tuple[tuple[slice, slice], np.ndarray]:
        x, y, r = post
        rows, cols = self._window(x - r, y - r, x + r, y + r, reach)
        d = np.hypot(self.xs[cols][None, :] - x, self.ys[rows][:, None] - y) - r
        return (rows, cols), np.maximum(d, 0.0)

    def _disk_distance(self, disks: np.ndarray, reach: float) -> tuple[tuple[slice, slice], np.ndarray]:
        lo = disks[:, :2].min(axis=0)
        hi = disks[:, :2].max(axis=0)
        rows, cols = self._window(lo[0], lo[1], hi[0], hi[1], reach + float(disks[:, 2].max()))
        dx = self.xs[cols][None, None, :] - disks[:, 0, None, None]
        dy = self.ys[rows][None, :, None] - disks[:, 1, None, None]
        d = np.sqrt(dx**2 + dy**2) - disks[:, 2, None, None]
        return (rows, cols), np.maximum(d.min(axis=0), 0.0)

    def obstacle_distance(self, reach_m: float) -> np.ndarray:
        """Distance [m] from each cell centre to the nearest obstacle (0 inside one), inf beyond `reach_m`."""
        out = np.full((self.ny, self.nx), np.inf)
        parts = [self._box_distance(b, reach_m) for b in self.boxes]
        parts += [self._wall_distance(w, reach_m) for w in self.walls]
        parts += [self._post_distance(p, reach_m) for p in self.posts]
        parts += [self._disk_distance(d, reach_m) for d in self.disks]
        for (rows, cols), d in parts:
            np.minimum(out[rows, cols], d, out=out[rows, cols])
        out[out > reach_m] = np.inf
        return out

    def wall_distance(self) -> np.ndarray:
        """Distance [m] from each cell centre to the arena's wall (0 for centres past the edge)."""
        dx = np.maximum(np.minimum(self.xs, self.width_m - self.xs), 0.0)
        dy = np.maximum(np.minimum(self.ys, self.height_m - self.ys), 0.0)
        return np.minimum(dx[None, :], dy[:, None])

    def wall_band(self, radius_m: float) -> np.ndarray:
        """Cells whose centre lies within `radius_m` of the wall (or past it)."""
        # min(dx, dy) <= r exactly when dx <= r or dy <= r: the same cells, no (ny, nx) distances.
        dx = np.maximum(np.minimum(self.xs, self.width_m - self.xs), 0.0)
        dy = np.maximum(np.minimum(self.ys, self.height_m - self.ys), 0.0)
        limit = radius_m + 1e-12
        return (dx <= limit)[None, :] | (dy <= limit)[:, None]

    def blocked_within(self, radius_m: float) -> np.ndarray:
        """Cells whose centre lies within `radius_m` of an obstacle or the wall: the inflated layer for that radius."""
        return (self.obstacle_distance(radius_m) <= radius_m + 1e-12) | self.wall_band(radius_m)

    # --- obstacles -----------------------------------------------------------------------

    def _grow(self, part: tuple[tuple[slice, slice], np.ndarray]) -> int:
        (rows, cols), d = part
        window = self.inflated[rows, cols]
        grown = d <= self.config.inflation_m + 1e-12
        newly = int(np.count_nonzero(grown & ~window))
        window |= grown
        return newly

    def add_box(self, x_m: float, y_m: float, w_m: float, h_m: float) -> int:
        """Add an obstacle box (centre, size [m]); returns how many cells it newly inflated."""
        if not (w_m > 0 and h_m > 0):
            raise ValueError(f"obstacle box size must be positive, got {w_m!r} × {h_m!r} m")
        box = (float(x_m), float(y_m), float(w_m), float(h_m))
        res = self.resolution_m
        c0, c1 = max(int(math.floor((x_m - w_m / 2) / res)), 0), min(int(math.ceil((x_m + w_m / 2) / res)), self.nx)
        r0, r1 = max(int(math.floor((y_m - h_m / 2) / res)), 0), min(int(math.ceil((y_m + h_m / 2) / res)), self.ny)
        self.raw[r0 : max(r1, r0), c0 : max(c1, c0)] = True
        self.boxes.append(box)
        self.version += 1
        # self._grow(self._box_distance(box, inflation)) compiled: the same cells, 6 µs a box
        # instead of 14 (40 boxes of up to 2 m on 400 × 400 cells).
        reach = self.config.inflation_m
        rows, cols = self._window(
            box[0] - box[2] / 2, box[1] - box[3] / 2, box[0] + box[2] / 2, box[1] + box[3] / 2, reach
        )
        return _grow_box(
            self.inflated,
            self.xs,
            self.ys,
            box[0],
            box[1],
            box[2] / 2,
            box[3] / 2,
            reach + 1e-12,
            rows.start,
            rows.stop,
            cols.start,
            cols.stop,
        )

    def add_wall(self, x0_m: float, y0_m: float, x1_m: float, y1_m: float, thickness_m: float) -> int:
        """Add a wall: the rectangle `thickness_m` wide centred on the segment from (x0, y0) to
        (x1, y1) [m], square ends flush with the end points; returns how many cells it newly
        inflated. A wall along x or y is the box it covers (add_box); an oblique one is inflated
        by the exact distance from each cell centre to its rectangle (the distance to the segment
        minus half the thickness, except off the square ends), and its raw cells are those the
        rectangle overlaps (a separating-axis test against each cell's square)."""
        values = (x0_m, y0_m, x1_m, y1_m, thickness_m)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"wall must be finite numbers, got {values!r}")
        if not thickness_m > 0:
            raise ValueError(f"wall thickness must be positive, got {thickness_m!r} m")
        length = math.hypot(x1_m - x0_m, y1_m - y0_m)
        if not length > 0:
            raise ValueError(f"wall must have a length, both ends at ({x0_m!r}, {y0_m!r})")
        if x0_m == x1_m:
            return self.add_box(x0_m, (y0_m + y1_m) / 2, thickness_m, abs(y1_m - y0_m))
        if y0_m == y1_m:
            return self.add_box((x0_m + x1_m) / 2, y0_m, abs(x1_m - x0_m), thickness_m)
        ux, uy = (x1_m - x0_m) / length, (y1_m - y0_m) / length
        wall = (
            float((x0_m + x1_m) / 2),
            float((y0_m + y1_m) / 2),
            float(ux),
            float(uy),
            float(length / 2),
            float(thickness_m / 2),
        )
        h = self.resolution_m / 2
        # A cell's square and the rectangle overlap unless an axis of either separates them: the
        # square's axes (x, y: within the rectangle's bounding box) or the rectangle's (along,
        # across: the square's half extent projected on them is h(|ux| + |uy|)).
        (rows, cols), along, across = self._wall_local(wall, h)
        a, b = wall[4], wall[5]
        ex, ey = abs(ux) * a + abs(uy) * b, abs(uy) * a + abs(ux) * b
        reach = h * (abs(ux) + abs(uy))
        inside_x = np.abs(self.xs[cols] - wall[0]) < ex + h
        inside_y = np.abs(self.ys[rows] - wall[1]) < ey + h
        overlap = (along < a + reach) & (across < b + reach) & inside_x[None, :] & inside_y[:, None]
        self.raw[rows, cols] |= overlap
        self.walls.append(wall)
        self.version += 1
        return self._grow(self._wall_distance(wall, self.config.inflation_m))

    def add_post(self, x_m: float, y_m: float, radius_m: float) -> int:
        """Add a round post (centre, radius [m]); returns how many cells it newly inflated. Its raw
        cells are those whose square the disk overlaps; the inflation is exact (distance from a
        cell centre to the post's centre, minus the radius)."""
        if not all(math.isfinite(v) for v in (x_m, y_m, radius_m)):
            raise ValueError(f"post must be finite numbers, got {(x_m, y_m, radius_m)!r}")
        if not radius_m > 0:
            raise ValueError(f"post radius must be positive, got {radius_m!r} m")
        post = (float(x_m), float(y_m), float(radius_m))
        h = self.resolution_m / 2
        rows, cols = self._window(x_m - radius_m, y_m - radius_m, x_m + radius_m, y_m + radius_m, h)
        # Nearest point of each cell's square to the centre.
        dx = np.maximum(np.abs(self.xs[cols] - x_m) - h, 0.0)
        dy = np.maximum(np.abs(self.ys[rows] - y_m) - h, 0.0)
        self.raw[rows, cols] |= np.hypot(dx[None, :], dy[:, None]) < radius_m
        self.posts.append(post)
        self.version += 1
        return self._grow(self._post_distance(post, self.config.inflation_m))

    def add_disks(self, centres_m: np.ndarray, radius_m: float) -> tuple[np.ndarray, int]:
        """Add small round obstacles (centres [m], one radius [m]); returns (new raw cells, newly inflated count).

        Centres off the arena are dropped. The raw layer gets the cells holding the centres.
        """
        pts = np.asarray(centres_m, dtype=np.float64).reshape(-1, 2)
        pts = pts[(pts[:, 0] >= 0) & (pts[:, 0] <= self.width_m) & (pts[:, 1] >= 0) & (pts[:, 1] <= self.height_m)]
        if not len(pts):
            return np.empty((0, 2), dtype=np.int64), 0
        res = self.resolution_m
        cells = np.stack(
            [
                np.minimum(np.floor(pts[:, 0] / res).astype(np.int64), self.nx - 1),
                np.minimum(np.floor(pts[:, 1] / res).astype(np.int64), self.ny - 1),
            ],
            axis=1,
        )
        cells = np.unique(cells, axis=0)
        new = cells[~self.raw[cells[:, 1], cells[:, 0]]]
        self.raw[cells[:, 1], cells[:, 0]] = True
        disks = np.column_stack([pts, np.full(len(pts), float(radius_m))])
        self.disks.append(disks)
        self.version += 1
        return new, self._grow(self._disk_distance(disks, self.config.inflation_m))

    # --- checks --------------------------------------------------------------------------

    def segment_clear(self, a: Sequence[float], b: Sequence[float]) -> bool:
        """Whether the rover's centre may drive straight from a to b [m] (see `segment`)."""
        if not (self.contains(*a) and self.contains(*b)):
            return False
        p = self.to_cell_units([a, b])
        return bool(segment_clear(self.inflated, p[0, 0], p[0, 1], p[1, 0], p[1, 1]))

    def path_blocked(self, path: Sequence[Sequence[float]]) -> bool:
        """Whether any segment of the path (waypoints [m]) leaves the arena or touches an inflated cell."""
        pts = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        if not len(pts):
            return False
        if not all(self.contains(x, y) for x, y in pts):
            return True
        return not bool(polyline_clear(self.inflated, self.to_cell_units(pts)))

    def __repr__(self) -> str:
        return (
            f"OccupancyGrid({self.width_m} × {self.height_m} m, {self.nx} × {self.ny} cells of "
            f"{self.resolution_m} m, {int(self.raw.sum())} raw / {int(self.inflated.sum())} inflated)"
        )
