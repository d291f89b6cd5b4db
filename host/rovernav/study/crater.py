"""A seeded, crater-like obstacle map the size of the report's Gale Crater map, and A* across it.

The map is a boolean image, True where the rover may not go, indexed [iy, ix] with row 0 at the
bottom (the planner's convention), `scale_m` metres per pixel, origin at the bottom-left corner.
Obstacles: crater rims (rings of random radius and width) and a large central mound (the
report's map has Aeolis Mons in the middle). Craters are placed so that none touches the
keep-clear points (P0, P1, P2 by default), so those points are free and never inside a rim.
The rover (about 3 m across) is far smaller than a pixel, so the map is not inflated.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ..planning import OccupancyGrid, PlanResult, plan
from ..planning.planner import warm_up
from ..planning.segment import polyline_clear
from .pose import REPORT_P0, REPORT_P1, save_figure

REPORT_P2 = (10_870.0, 25_670.0)  # eq. 3.1 [m]
MAP_WIDTH_M = 50_000.0  # the report's map: about 50 km × 35 km
MAP_HEIGHT_M = 35_000.0


@dataclasses.dataclass(frozen=True)
class CraterMap:
    """obstacles: (ny, nx) bool, True = blocked; scale_m: metres per pixel."""

    obstacles: np.ndarray
    scale_m: float
    craters: tuple[tuple[float, float, float, float], ...]  # (x, y, radius, rim width) [m]
    mound: tuple[float, float, float, float]  # (x, y, semi-axis x, semi-axis y) [m]

    @property
    def width_m(self) -> float:
        return self.obstacles.shape[1] * self.scale_m

    @property
    def height_m(self) -> float:
        return self.obstacles.shape[0] * self.scale_m

    def is_free(self, x_m: float, y_m: float) -> bool:
        ix, iy = int(x_m // self.scale_m), int(y_m // self.scale_m)
        ny, nx = self.obstacles.shape
        return 0 <= ix < nx and 0 <= iy < ny and not self.obstacles[iy, ix]

    def grid(self) -> OccupancyGrid:
        """The map as the planner's grid, one cell per pixel."""
        return OccupancyGrid.from_layers(self.obstacles, resolution_m=self.scale_m)


def crater_map(
    seed: int = 0,
    scale_m: float = 50.0,
    n_craters: int = 180,
    radius_range_m: tuple[float, float] = (300.0, 4_000.0),
    keep_clear: Sequence[Sequence[float]] = (REPORT_P0[:2], REPORT_P1[:2], REPORT_P2),
    clearance_m: float = 500.0,
    mound: tuple[float, float, float, float] = (24_000.0, 11_500.0, 8_000.0, 5_000.0),
    keep_clear_path: np.ndarray | None = None,
) -> CraterMap:
    """Generate a map of MAP_WIDTH_M × MAP_HEIGHT_M at `scale_m` m/pixel, the same for the same seed.

    Crater radii follow a power law (many small, few large) within `radius_range_m`; rim width is
    15 % of the radius, at least two pixels. A crater is redrawn when its rim would come within
    `clearance_m` of a keep-clear point or would enclose one; the mound, an ellipse, must not
    cover one either (ValueError). `keep_clear_path`, an (n, 2) array of points [m] sampled
    closer than a rim's width (e.g. the pose law's trajectory), keeps rims off a route the
    same way (a crater may still hold a stretch of it wholly inside).
    """
    if not (scale_m > 0 and math.isfinite(scale_m)):
        raise ValueError(f"scale_m must be a positive length [m], got {scale_m!r}")
    rng = np.random.default_rng(seed)
    nx = int(round(MAP_WIDTH_M / scale_m))
    ny = int(round(MAP_HEIGHT_M / scale_m))
    xs = (np.arange(nx) + 0.5) * scale_m
    ys = (np.arange(ny) + 0.5) * scale_m
    blocked = np.zeros((ny, nx), dtype=np.bool_)
    points = np.asarray(keep_clear, dtype=np.float64).reshape(-1, 2)

    mx, my, ax, ay = mound
    inside = ((points[:, 0] - mx) / ax) ** 2 + ((points[:, 1] - my) / ay) ** 2
    if np.any(inside <= 1.0):
        raise ValueError("the central mound covers a keep-clear point")
    blocked |= ((xs[None, :] - mx) / ax) ** 2 + ((ys[:, None] - my) / ay) ** 2 <= 1.0

    route = None if keep_clear_path is None else np.asarray(keep_clear_path, dtype=np.float64).reshape(-1, 2)
    r_lo, r_hi = radius_range_m
    craters = []
    attempts = 0
    while len(craters) < n_craters and attempts < 50 * n_craters:
        attempts += 1
        # Inverse-CDF of a power law p(r) ∝ r^-2 between r_lo and r_hi.
        u = rng.random()
        r = 1.0 / (1.0 / r_lo - u * (1.0 / r_lo - 1.0 / r_hi))
        w = max(0.15 * r, 2.0 * scale_m)
        cx, cy = rng.uniform(0, nx * scale_m), rng.uniform(0, ny * scale_m)
        d = np.hypot(points[:, 0] - cx, points[:, 1] - cy)
        if np.any(d < r + w / 2 + clearance_m):  # near the rim, or inside the crater
            continue
        if route is not None and np.any(np.abs(np.hypot(route[:, 0] - cx, route[:, 1] - cy) - r) < w / 2 + clearance_m):
            continue
        craters.append((cx, cy, r, w))
        c0, c1 = max(int((cx - r - w) / scale_m), 0), min(int((cx + r + w) / scale_m) + 1, nx)
        r0, r1 = max(int((cy - r - w) / scale_m), 0), min(int((cy + r + w) / scale_m) + 1, ny)
        if c0 >= c1 or r0 >= r1:
            continue
        dist = np.hypot(xs[None, c0:c1] - cx, ys[r0:r1, None] - cy)
        blocked[r0:r1, c0:c1] |= np.abs(dist - r) <= w / 2
    return CraterMap(obstacles=blocked, scale_m=float(scale_m), craters=tuple(craters), mound=tuple(mound))


def plan_on_map(
    cmap: CraterMap, start_xy: Sequence[float] = REPORT_P1[:2], goal_xy: Sequence[float] = REPORT_P2
) -> PlanResult:
    """A* on the map's pixels (the report's "pixel domain") from `start_xy` to `goal_xy` [m].

    Raises the planner's NoPathError when the map has no way through.
    """
    warm_up()
    return plan(cmap.grid(), start_xy, goal_xy, planner="astar")


def path_is_clear(cmap: CraterMap, waypoints: Sequence[Sequence[float]]) -> bool:
    """Whether every segment between `waypoints` [m] keeps off the obstacle pixels."""
    grid = cmap.grid()
    return bool(polyline_clear(grid.inflated, grid.to_cell_units(np.asarray(waypoints, dtype=np.float64))))


def plot_crater_plan(
    cmap: CraterMap, result: PlanResult | None, path: str, trajectory_xy: np.ndarray | None = None
) -> None:
    """The map, the A* path P1 → P2 (and optionally the pose-law trajectory, an (n, 2) array [m]) to a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 7.5))
    ax.imshow(cmap.obstacles, origin="lower", cmap="Greys", extent=(0, cmap.width_m / 1e3, 0, cmap.height_m / 1e3))
    if trajectory_xy is not None:
        ax.plot(trajectory_xy[:, 0] / 1e3, trajectory_xy[:, 1] / 1e3, "b-", lw=1.5, label="pose law P0 → P1")
    if result is not None:
        wp = np.asarray(result.waypoints)
        ax.plot(
            wp[:, 0] / 1e3,
            wp[:, 1] / 1e3,
            "r-",
            lw=1.8,
            label=f"A* P1 → P2: {result.length_m / 1e3:.2f} km, {result.time_s * 1e3:.0f} ms",
        )
    for name, (px, py) in (("P0", REPORT_P0[:2]), ("P1", REPORT_P1[:2]), ("P2", REPORT_P2)):
        ax.plot(px / 1e3, py / 1e3, "o", ms=7)
        ax.annotate(name, (px / 1e3, py / 1e3), textcoords="offset points", xytext=(6, 6))
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.set_title(f"Crater map ({cmap.scale_m:g} m/pixel) and reference path")
    ax.legend(loc="lower right")
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=110)  # atomically: never half a PNG
    finally:
        plt.close(fig)
