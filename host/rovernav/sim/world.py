"""The arena the simulated rover lives in: its walls, boxes, walls inside it, posts, and the
geometry the sensors need.

Units: metres; origin at the bottom-left corner; x right, y up; headings in degrees clockwise
from +y. Every obstacle of the scenario exists here, known to the planner or not.

Shapes: a Box is axis-aligned; a Wall is an oriented rectangle (a segment with a thickness,
square ends flush with its end points); a Post is a disk. Contact and clearance between the
rover's footprint (a rectangle at any heading) and each of them are exact: a wall is handled as a
box in its own frame (the footprint turned into it), a post by the distance from its centre to
the footprint polygon.

The sonar (`sonar_m`): rays sampled across the beam's cone, each stopping at the first surface it
meets. Sound reflects off a smooth flat face (a box's side, a wall's side or end, the arena's
wall) like light off a mirror: the echo comes back to the sensor only when the ray meets the face
nearly square on. A ray whose angle to the face's normal is above `max_incidence_deg` is lost (it
is neither heard nor followed: no multipath). A post is a cylinder: some part of it always faces
the sensor, so every ray that meets it echoes. A corner of a box or a wall (a vertical edge)
scatters sound every way, so it echoes whenever it lies inside the cone, in sight of the sensor.
With max_incidence_deg ≥ 90 every ray that meets a surface echoes and corners are not looked at
separately: the nearest surface along the rays, the model before posts and walls existed.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..scenario import Post, Wall  # the same in the scenario and the world: one definition each
from ..vehicle_gen import BODY_LENGTH_MM, BODY_WIDTH_MM

ROVER_WIDTH_M = BODY_WIDTH_MM / 1000.0  # protocol/vehicle.toml
ROVER_LENGTH_M = BODY_LENGTH_MM / 1000.0
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
    return np.array(_corners(x_m, y_m, heading_deg))


def _corners(x_m: float, y_m: float, heading_deg: float) -> list[tuple[float, float]]:
    """`footprint` in plain floats (the clearance test runs it most steps), each coordinate the
    same sum as numpy's centre + half-length * forward -/+ half-width * right."""
    h = math.radians(heading_deg)
    fx, fy = math.sin(h), math.cos(h)  # forward
    rx, ry = math.cos(h), -math.sin(h)  # right
    hl, hw = ROVER_LENGTH_M / 2, ROVER_WIDTH_M / 2
    ax, ay = x_m + hl * fx, y_m + hl * fy  # the front's middle
    bx, by = x_m - hl * fx, y_m - hl * fy  # the back's
    wx, wy = hw * rx, hw * ry
    return [(ax - wx, ay - wy), (ax + wx, ay + wy), (bx + wx, by + wy), (bx - wx, by - wy)]


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


def _poly_circle_distance(pts: list[tuple[float, float]], x: float, y: float, r: float) -> float:
    """Distance between a convex polygon and a disk (0 if they touch or overlap)."""
    n = len(pts)
    best = math.inf
    inside = True
    sign = 0.0
    for i in range(n):
        ax, ay = pts[i]
        bx, by = pts[(i + 1) % n]
        ex, ey = bx - ax, by - ay
        cross = ex * (y - ay) - ey * (x - ax)
        if cross != 0.0:
            if sign == 0.0:
                sign = cross
            elif (cross > 0) != (sign > 0):
                inside = False
        ee = ex * ex + ey * ey or 1e-12
        t = min(1.0, max(0.0, ((x - ax) * ex + (y - ay) * ey) / ee))
        best = min(best, math.hypot(x - ax - t * ex, y - ay - t * ey))
    if inside:
        return 0.0
    return max(0.0, best - r)


def _local(pts: list[tuple[float, float]], frame: tuple[float, ...]) -> list[tuple[float, float]]:
    """Points in a wall's frame: (along the wall, across it) from its centre."""
    cx, cy, ux, uy = frame[:4]
    return [((px - cx) * ux + (py - cy) * uy, (py - cy) * ux - (px - cx) * uy) for px, py in pts]


def _rect_point_distance(frame: tuple[float, ...], x: float, y: float) -> float:
    """Distance from a point to a wall's rectangle (0 inside)."""
    cx, cy, ux, uy, a, b = frame
    dx, dy = x - cx, y - cy
    return math.hypot(max(abs(dx * ux + dy * uy) - a, 0.0), max(abs(dy * ux - dx * uy) - b, 0.0))


def _slab_hit(
    px: float, py: float, dx: float, dy: float, x0: float, y0: float, x1: float, y1: float, t_max: float
) -> tuple[float, int] | None:
    """Where the ray p + t·d (t ≥ 0) enters the box [x0, x1] × [y0, y1] before t_max: (t, the axis
    of the face it enters by: 0 for a face across x, 1 across y, -1 when it starts inside)."""
    tmin, tmax, axis = 0.0, t_max, -1
    for k, (p, v, lo, hi) in enumerate(((px, dx, x0, x1), (py, dy, y0, y1))):
        if abs(v) < 1e-12:
            if p < lo or p > hi:
                return None
            continue
        t1, t2 = (lo - p) / v, (hi - p) / v
        if t1 > t2:
            t1, t2 = t2, t1
        if t1 > tmin:
            tmin, axis = t1, k
        tmax = min(tmax, t2)
        if tmin > tmax:
            return None
    return tmin, axis


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
    """The arena's walls, boxes, walls inside it and posts; collision, clearance and sonar geometry."""

    def __init__(
        self, width_m: float, height_m: float, boxes: list[Box], walls: list[Wall] = (), posts: list[Post] = ()
    ):
        self.width_m = width_m
        self.height_m = height_m
        self.boxes = list(boxes)
        self.walls = list(walls)
        self.posts = list(posts)
        self._frames = [w.frame() for w in self.walls]
        # Every corner of a box or a wall: the edges that echo from any direction.
        corners = [
            c
            for b in self.boxes
            for c in (
                (b.bounds[0], b.bounds[1]),
                (b.bounds[2], b.bounds[1]),
                (b.bounds[2], b.bounds[3]),
                (b.bounds[0], b.bounds[3]),
            )
        ]
        corners += [c for w in self.walls for c in w.corners()]
        self._corners = np.array(corners, dtype=np.float64).reshape(-1, 2)

    @classmethod
    def from_scenario(cls, scenario) -> World:
        walls = getattr(scenario, "walls", ())
        posts = getattr(scenario, "posts", ())
        return cls(
            scenario.arena.width_m,
            scenario.arena.height_m,
            [Box(o.x_m, o.y_m, o.w_m, o.h_m, o.known) for o in scenario.obstacles],
            list(walls),
            list(posts),
        )

    # ---------------------------------------------------------------- contact and clearance

    def _distances(self, x_m: float, y_m: float, heading_deg: float, best: float, cull: bool):
        """(distance, what) for each obstacle the footprint might be nearer to than `best`
        (every obstacle when not `cull`); what is ("box" | "wall" | "post", index)."""
        pts = _corners(x_m, y_m, heading_deg)
        for i, b in enumerate(self.boxes):
            x0, y0, x1, y1 = b.bounds
            # The footprint lies within HALF_DIAGONAL of the centre: an obstacle further than that
            # plus the best so far cannot be nearer. Only close ones get the exact test.
            if cull and math.hypot(max(x0 - x_m, 0.0, x_m - x1), max(y0 - y_m, 0.0, y_m - y1)) - HALF_DIAGONAL_M > best:
                continue
            d = _poly_box_distance(pts, b.bounds)
            best = min(best, d)
            yield d, ("box", i)
        for i, f in enumerate(self._frames):
            if cull and _rect_point_distance(f, x_m, y_m) - HALF_DIAGONAL_M > best:
                continue
            d = _poly_box_distance(_local(pts, f), (-f[4], -f[5], f[4], f[5]))
            best = min(best, d)
            yield d, ("wall", i)
        for i, p in enumerate(self.posts):
            if cull and math.hypot(p.x_m - x_m, p.y_m - y_m) - p.radius_m - HALF_DIAGONAL_M > best:
                continue
            d = _poly_circle_distance(pts, p.x_m, p.y_m, p.radius_m)
            best = min(best, d)
            yield d, ("post", i)

    def clearance_m(self, x_m: float, y_m: float, heading_deg: float) -> float:
        """Distance from the rover's footprint to the nearest obstacle or wall (0: contact)."""
        pts = _corners(x_m, y_m, heading_deg)
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        best = max(0.0, min(min(xs), min(ys), self.width_m - max(xs), self.height_m - max(ys)))
        for d, _ in self._distances(x_m, y_m, heading_deg, best, cull=True):
            best = min(best, d)
        return best

    def clearance_bound_m(self, x_m: float, y_m: float) -> float:
        """A lower bound of clearance_m, whatever the heading: the distance from the circle that
        holds the footprint to the nearest wall, box or post."""
        best = min(x_m, y_m, self.width_m - x_m, self.height_m - y_m)
        for b in self.boxes:
            x0, y0, x1, y1 = b.bounds
            best = min(best, math.hypot(max(x0 - x_m, 0.0, x_m - x1), max(y0 - y_m, 0.0, y_m - y1)))
        for f in self._frames:
            best = min(best, _rect_point_distance(f, x_m, y_m))
        for p in self.posts:
            best = min(best, math.hypot(p.x_m - x_m, p.y_m - y_m) - p.radius_m)
        return best - HALF_DIAGONAL_M

    def describe(self, what: tuple[str, int]) -> str:
        """An obstacle by its kind and number in the scenario (from 1), e.g. "wall 2 (unknown, from
        (0.50, 0.00) to (0.50, 0.80) m, 0.05 m thick)"."""
        kind, i = what
        if kind == "box":
            b = self.boxes[i]
            return (
                f"obstacle {i + 1} ({'known' if b.known else 'unknown'} box at "
                f"({b.x_m:.2f}, {b.y_m:.2f}) m, {b.w_m:.2f} x {b.h_m:.2f} m)"
            )
        if kind == "wall":
            w = self.walls[i]
            return (
                f"wall {i + 1} ({'known' if w.known else 'unknown'}, from ({w.x0_m:.2f}, {w.y0_m:.2f}) "
                f"to ({w.x1_m:.2f}, {w.y1_m:.2f}) m, {w.thickness_m:.2f} m thick)"
            )
        p = self.posts[i]
        return (
            f"post {i + 1} ({'known' if p.known else 'unknown'}, at ({p.x_m:.2f}, {p.y_m:.2f}) m, "
            f"radius {p.radius_m:.3f} m)"
        )

    def touching(self, x_m: float, y_m: float, heading_deg: float) -> str:
        """What the rover's footprint touches (or comes nearest to): "the left wall", or a box,
        wall or post described by its number in the scenario, where it is and whether the planner
        knew it."""
        poly = footprint(x_m, y_m, heading_deg)
        xs, ys = poly[:, 0], poly[:, 1]
        walls = {
            "the left wall": xs.min(),
            "the bottom wall": ys.min(),
            "the right wall": self.width_m - xs.max(),
            "the top wall": self.height_m - ys.max(),
        }
        best_name, best = min(walls.items(), key=lambda kv: kv[1])
        for d, what in self._distances(x_m, y_m, heading_deg, math.inf, cull=False):
            if d < best:
                best, best_name = d, self.describe(what)
        return best_name

    def collides(self, x_m: float, y_m: float, heading_deg: float) -> bool:
        return self.clearance_m(x_m, y_m, heading_deg) <= 0.0

    # ---------------------------------------------------------------- rays and the sonar

    def cast(self, x_m: float, y_m: float, direction_deg: float, max_m: float) -> tuple[float, float]:
        """The first surface along a ray: (distance, cosine of the angle between the ray and the
        surface's normal there). (max_m, 0) if nothing is nearer; the cosine is 1 for a post (some
        part of it always faces the sensor) and for a ray that starts inside an obstacle."""
        d = math.radians(direction_deg)
        dx, dy = math.sin(d), math.cos(d)
        best, cos = max_m, 0.0
        # the arena's walls
        if dx > 1e-9 and (self.width_m - x_m) / dx < best:
            best, cos = (self.width_m - x_m) / dx, abs(dx)
        elif dx < -1e-9 and -x_m / dx < best:
            best, cos = -x_m / dx, abs(dx)
        if dy > 1e-9 and (self.height_m - y_m) / dy <= best:
            t = (self.height_m - y_m) / dy
            best, cos = t, max(cos, abs(dy)) if t == best else abs(dy)
        elif dy < -1e-9 and -y_m / dy <= best:
            t = -y_m / dy
            best, cos = t, max(cos, abs(dy)) if t == best else abs(dy)
        # boxes (slab method)
        for b in self.boxes:
            x0, y0, x1, y1 = b.bounds
            hit = _slab_hit(x_m, y_m, dx, dy, x0, y0, x1, y1, best)
            if hit is not None and hit[0] < best:
                best, cos = hit[0], (1.0 if hit[1] < 0 else abs(dx) if hit[1] == 0 else abs(dy))
        # walls: the slab method in each wall's frame
        for cx, cy, ux, uy, a, b in self._frames:
            px, py = (x_m - cx) * ux + (y_m - cy) * uy, (y_m - cy) * ux - (x_m - cx) * uy
            ldx, ldy = dx * ux + dy * uy, dy * ux - dx * uy
            hit = _slab_hit(px, py, ldx, ldy, -a, -b, a, b, best)
            if hit is not None and hit[0] < best:
                best, cos = hit[0], (1.0 if hit[1] < 0 else abs(ldx) if hit[1] == 0 else abs(ldy))
        # posts
        for p in self.posts:
            fx, fy = x_m - p.x_m, y_m - p.y_m
            c = fx * fx + fy * fy - p.radius_m * p.radius_m
            if c <= 0.0:
                best, cos = 0.0, 1.0
                continue
            bb = fx * dx + fy * dy
            disc = bb * bb - c
            if bb < 0.0 and disc >= 0.0:
                t = -bb - math.sqrt(disc)
                if t < best:
                    best, cos = t, 1.0
        return max(0.0, best), cos

    def ray_m(self, x_m: float, y_m: float, direction_deg: float, max_m: float) -> float:
        """Distance along a ray to the first wall, box or post (max_m if none nearer)."""
        return self.cast(x_m, y_m, direction_deg, max_m)[0]

    def echo_m(
        self, x_m: float, y_m: float, direction_deg: float, max_m: float, max_incidence_deg: float = 90.0
    ) -> float:
        """Distance along a ray to the first surface if it echoes back, max_m if not (nothing
        there, or a flat face met more than max_incidence_deg off its normal: the sound goes away)."""
        t, cos = self.cast(x_m, y_m, direction_deg, max_m)
        if t >= max_m or max_incidence_deg >= 90.0:
            return t
        return t if cos >= math.cos(math.radians(max_incidence_deg)) - 1e-12 else max_m

    def corner_echo_m(self, x_m: float, y_m: float, axis_deg: float, cone_deg: float, max_m: float) -> float:
        """Distance to the nearest corner of a box or a wall inside the cone (half cone_deg either
        side of axis_deg) that the sensor at (x, y) can see; max_m if none."""
        if not len(self._corners):
            return max_m
        d = self._corners - (x_m, y_m)
        dist = np.hypot(d[:, 0], d[:, 1])
        a = math.radians(axis_deg)
        along = d[:, 0] * math.sin(a) + d[:, 1] * math.cos(a)
        cand = np.nonzero((dist < max_m) & (dist > 1e-9) & (along >= dist * math.cos(math.radians(cone_deg / 2))))[0]
        for k in cand[np.argsort(dist[cand], kind="stable")]:
            r = float(dist[k])
            bearing = math.degrees(math.atan2(float(d[k, 0]), float(d[k, 1])))
            if self.ray_m(x_m, y_m, bearing, r + 1e-3) >= r - 1e-3:  # nothing in front of it
                return r
        return max_m

    def sonar_m(
        self,
        x_m: float,
        y_m: float,
        axis_deg: float,
        cone_deg: float,
        max_m: float,
        max_incidence_deg: float = 90.0,
        rays: int = 7,
    ) -> float:
        """One ping of a sensor at (x, y) pointing along axis_deg: the nearest echo within the cone
        (`rays` rays across it, corners in it), or max_m if nothing echoes (see the module's notes)."""
        half = cone_deg / 2
        nearest = min(
            self.echo_m(x_m, y_m, axis_deg + a, max_m, max_incidence_deg) for a in np.linspace(-half, half, rays)
        )
        if max_incidence_deg < 90.0:
            nearest = min(nearest, self.corner_echo_m(x_m, y_m, axis_deg, cone_deg, nearest))
        return nearest
