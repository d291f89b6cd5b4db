"""The arena the simulated rover lives in: walls, boxes, and the geometry the sensors need.

Units: metres; origin at the bottom-left corner; x right, y up; headings in degrees clockwise
from +y. Every obstacle of the scenario exists here, known to the planner or not.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

ROVER_WIDTH_M = 0.15    # the seed's rover: 0.15 m wide, 0.21 m long
ROVER_LENGTH_M = 0.21
HALF_DIAGONAL_M = math.hypot(ROVER_WIDTH_M, ROVER_LENGTH_M) / 2


@dataclasses.dataclass(frozen=True)
class Box:
    """An axis-aligned obstacle: centre and size."""

    x_m: float
    y_m: float
    w_m: float
    h_m: float
    known: bool = True

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (self.x_m - self.w_m / 2, self.y_m - self.h_m / 2, self.x_m + self.w_m / 2, self.y_m + self.h_m / 2)


def footprint(x_m: float, y_m: float, heading_deg: float) -> np.ndarray:
    """The rover's rectangle as 4 corners (front-left, front-right, back-right, back-left)."""
    h = math.radians(heading_deg)
    f = np.array([math.sin(h), math.cos(h)])      # forward
    r = np.array([math.cos(h), -math.sin(h)])     # right
    c = np.array([x_m, y_m])
    hl, hw = ROVER_LENGTH_M / 2, ROVER_WIDTH_M / 2
    return np.array([c + hl * f - hw * r, c + hl * f + hw * r, c - hl * f + hw * r, c - hl * f - hw * r])


def _poly_box_distance(poly: np.ndarray, box: tuple[float, float, float, float]) -> float:
    """Distance between a convex polygon and an axis-aligned box (0 if they touch or overlap).

    Plain floats, no numpy: it runs for every step the rover is near a box.
    """
    x0, y0, x1, y1 = box
    pts = [(float(p[0]), float(p[1])) for p in poly]
    if _overlaps(pts, box):
        return 0.0
    best = math.inf
    for px, py in pts:  # polygon corners to the box
        dx = max(x0 - px, 0.0, px - x1)
        dy = max(y0 - py, 0.0, py - y1)
        best = min(best, math.hypot(dx, dy))
    corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    n = len(pts)
    for i in range(n):  # box corners to the polygon's edges
        ax, ay = pts[i]
        bx, by = pts[(i + 1) % n]
        ex, ey = bx - ax, by - ay
        ee = ex * ex + ey * ey or 1e-12
        for cx, cy in corners:
            t = min(1.0, max(0.0, ((cx - ax) * ex + (cy - ay) * ey) / ee))
            best = min(best, math.hypot(cx - ax - t * ex, cy - ay - t * ey))
    return best


def _overlaps(pts: list[tuple[float, float]], box: tuple[float, float, float, float]) -> bool:
    """Separating-axis test of a convex polygon against an axis-aligned box."""
    x0, y0, x1, y1 = box
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    if max(xs) < x0 or min(xs) > x1 or max(ys) < y0 or min(ys) > y1:
        return False
    corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    n = len(pts)
    for i in range(n):
        ax, ay = pts[i]
        bx, by = pts[(i + 1) % n]
        nx, ny = -(by - ay), bx - ax
        pp = [px * nx + py * ny for px, py in pts]
        cc = [cx * nx + cy * ny for cx, cy in corners]
        if max(pp) < min(cc) or max(cc) < min(pp):
            return False
    return True


class World:
    """Walls and boxes; collision, clearance and sonar geometry."""

    def __init__(self, width_m: float, height_m: float, boxes: list[Box]):
        self.width_m = width_m
        self.height_m = height_m
        self.boxes = list(boxes)

    @classmethod
    def from_scenario(cls, scenario) -> "World":
        return cls(scenario.arena.width_m, scenario.arena.height_m,
                   [Box(o.x_m, o.y_m, o.w_m, o.h_m, o.known) for o in scenario.obstacles])

    def clearance_m(self, x_m: float, y_m: float, heading_deg: float) -> float:
        """Distance from the rover's footprint to the nearest obstacle or wall (0: contact)."""
        poly = footprint(x_m, y_m, heading_deg)
        xs, ys = poly[:, 0], poly[:, 1]
        best = max(0.0, float(min(xs.min(), ys.min(), self.width_m - xs.max(), self.height_m - ys.max())))
        for b in self.boxes:
            x0, y0, x1, y1 = b.bounds
            # The footprint lies within HALF_DIAGONAL of the centre: a box further than that plus
            # the best so far cannot be nearer. Only close boxes get the exact test.
            cx, cy = min(max(x_m, x0), x1), min(max(y_m, y0), y1)
            if math.hypot(cx - x_m, cy - y_m) - HALF_DIAGONAL_M > best:
                continue
            best = min(best, _poly_box_distance(poly, b.bounds))
        return best

    def clearance_bound_m(self, x_m: float, y_m: float) -> float:
        """A lower bound of clearance_m, whatever the heading: the distance from the circle that
        holds the footprint to the nearest wall or box."""
        best = min(x_m, y_m, self.width_m - x_m, self.height_m - y_m)
        for b in self.boxes:
            x0, y0, x1, y1 = b.bounds
            best = min(best, math.hypot(max(x0 - x_m, 0.0, x_m - x1), max(y0 - y_m, 0.0, y_m - y1)))
        return best - HALF_DIAGONAL_M

    def touching(self, x_m: float, y_m: float, heading_deg: float) -> str:
        """What the rover's footprint touches (or comes nearest to): "the left wall", or a box
        described by its number in the scenario, centre and whether the planner knew it."""
        poly = footprint(x_m, y_m, heading_deg)
        xs, ys = poly[:, 0], poly[:, 1]
        walls = {"the left wall": xs.min(), "the bottom wall": ys.min(),
                 "the right wall": self.width_m - xs.max(), "the top wall": self.height_m - ys.max()}
        best_name, best = min(walls.items(), key=lambda kv: kv[1])
        for i, b in enumerate(self.boxes):
            d = _poly_box_distance(poly, b.bounds)
            if d < best:
                best = d
                best_name = (f"obstacle {i + 1} ({'known' if b.known else 'unknown'} box at "
                             f"({b.x_m:.2f}, {b.y_m:.2f}) m, {b.w_m:.2f} x {b.h_m:.2f} m)")
        return best_name

    def collides(self, x_m: float, y_m: float, heading_deg: float) -> bool:
        return self.clearance_m(x_m, y_m, heading_deg) <= 0.0

    def ray_m(self, x_m: float, y_m: float, direction_deg: float, max_m: float) -> float:
        """Distance along a ray to the first wall or box (max_m if none nearer)."""
        d = math.radians(direction_deg)
        dx, dy = math.sin(d), math.cos(d)
        best = max_m
        # walls
        if dx > 1e-9:
            best = min(best, (self.width_m - x_m) / dx)
        elif dx < -1e-9:
            best = min(best, -x_m / dx)
        if dy > 1e-9:
            best = min(best, (self.height_m - y_m) / dy)
        elif dy < -1e-9:
            best = min(best, -y_m / dy)
        # boxes (slab method)
        for b in self.boxes:
            x0, y0, x1, y1 = b.bounds
            tmin, tmax = 0.0, best
            hit = True
            for p, v, lo, hi in ((x_m, dx, x0, x1), (y_m, dy, y0, y1)):
                if abs(v) < 1e-12:
                    if p < lo or p > hi:
                        hit = False
                        break
                    continue
                t1, t2 = (lo - p) / v, (hi - p) / v
                if t1 > t2:
                    t1, t2 = t2, t1
                tmin, tmax = max(tmin, t1), min(tmax, t2)
                if tmin > tmax:
                    hit = False
                    break
            if hit and tmin < best:
                best = tmin
        return max(0.0, best)
