"""What a family draws: the arena's size and the obstacles' (boxes, walls, posts), the random
choices of one draw, and the errors of the generator."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...angles import compass_deg
from ...errors import InputError, PlanningError
from ...planning import NoPathError, OccupancyGrid, PlannerConfig, PlanResult, plan

ARENA_WIDTH_RANGE_M = (2.0, 3.0)
ARENA_HEIGHT_RANGE_M = (1.5, 2.2)
WALL_THICKNESS_RANGE_M = (0.04, 0.06)
# The seed's boxes: 0.08 m (small obstacles), 0.15, 0.18, 0.25, 0.30 × 0.15 (out-and-back), 0.20 (Fig. 4.8).
SEED_BOX_SIZES_M = ((0.08, 0.08), (0.15, 0.15), (0.18, 0.18), (0.20, 0.20), (0.25, 0.25), (0.30, 0.15), (0.15, 0.30))
POST_DIAMETERS_M = (0.05, 0.06, 0.08, 0.10)  # table legs, pipes, pillars: the clutter family's posts
KEEP_CLEAR_M = 0.03  # beyond the inflation: a box keeps the start's and target's cells free
END_MARGIN_M = 0.06  # beyond the inflation: start and target from the arena's wall
NARROW_EXTRA_M = 0.06  # narrow passages: 2 × inflation to 2 × inflation + this
START_AT_TARGET_RANGE_M = (0.021, 0.049)


class ArenaError(InputError):
    """A request the generator cannot serve: a bad count, seed, family or output folder."""


class GenerationFailed(PlanningError):
    """No draw of an arena met its family's constraints within MAX_TRIES."""


class _Redraw(Exception):
    """This draw broke a constraint: draw the arena again."""


# --- what a family draws ---------------------------------------------------------------------


@dataclasses.dataclass
class _Box:
    """An axis-aligned obstacle by its edges [m]: a box, or a wall (written as [[walls]] along
    its longer side); `role` becomes a comment in the file."""

    x0: float
    x1: float
    y0: float
    y1: float
    known: bool
    role: str
    shape: str = "box"  # or "wall"

    def distance_to(self, x_m: float, y_m: float) -> float:
        dx = max(self.x0 - x_m, 0.0, x_m - self.x1)
        dy = max(self.y0 - y_m, 0.0, y_m - self.y1)
        return math.hypot(dx, dy)

    def gap_to(self, other: _Box | _Post) -> float:
        if isinstance(other, _Post):
            return other.gap_to(self)
        dx = max(self.x0 - other.x1, other.x0 - self.x1, 0.0)
        dy = max(self.y0 - other.y1, other.y0 - self.y1, 0.0)
        return math.hypot(dx, dy)

    def on_arena(self, width_m: float, height_m: float) -> bool:
        return self.x0 >= 0 and self.y0 >= 0 and self.x1 <= width_m and self.y1 <= height_m


@dataclasses.dataclass
class _Post:
    """A round post [m]."""

    x: float
    y: float
    r: float
    known: bool
    role: str

    def distance_to(self, x_m: float, y_m: float) -> float:
        return max(math.hypot(x_m - self.x, y_m - self.y) - self.r, 0.0)

    def gap_to(self, other: _Box | _Post) -> float:
        if isinstance(other, _Post):
            return max(math.hypot(other.x - self.x, other.y - self.y) - self.r - other.r, 0.0)
        return max(other.distance_to(self.x, self.y) - self.r, 0.0)

    def on_arena(self, width_m: float, height_m: float) -> bool:
        return (
            self.x - self.r >= 0 and self.y - self.r >= 0 and self.x + self.r <= width_m and self.y + self.r <= height_m
        )


@dataclasses.dataclass
class _Seg:
    """A wall at any angle: the centre line's ends and the thickness [m]."""

    x0: float
    y0: float
    x1: float
    y1: float
    thickness: float
    known: bool
    role: str


@dataclasses.dataclass
class _Layout:
    """One drawn arena, before it is checked and measured."""

    width_m: float
    height_m: float
    start: tuple[float, float]
    heading_deg: float
    target: tuple[float, float]
    boxes: list[_Box]  # boxes and axis-aligned walls
    note: str  # what this arena is, for the description
    kind: str = "reach"
    trips: int = 1
    passage_width_m: float | None = None
    segs: list[_Seg] = dataclasses.field(default_factory=list)  # walls at an angle
    posts: list[_Post] = dataclasses.field(default_factory=list)


class _Draw:
    """The random choices of one draw: numbers on a millimetre grid from the arena's stream."""

    def __init__(self, rng: np.random.Generator, config: PlannerConfig):
        self.rng = rng
        self.config = config
        self.inflation_m = config.inflation_m
        self.width_m = self.u(*ARENA_WIDTH_RANGE_M, step_m=0.01)
        self.height_m = self.u(*ARENA_HEIGHT_RANGE_M, step_m=0.01)
        self.margin_m = self.inflation_m + END_MARGIN_M  # start and target from the wall
        self.clear_m = self.inflation_m + KEEP_CLEAR_M  # a box from the start and the target

    def u(self, lo: float, hi: float, step_m: float = 0.001) -> float:
        """A uniform multiple of `step_m` in [lo, hi]; _Redraw when there is none."""
        k_lo = math.ceil(lo / step_m - 1e-9)
        k_hi = math.floor(hi / step_m + 1e-9)
        if k_hi < k_lo:
            raise _Redraw(f"empty range [{lo}, {hi}]")
        return round(int(self.rng.integers(k_lo, k_hi + 1)) * step_m, 6)

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    def pick(self, options: Sequence[Any]) -> Any:
        return options[int(self.rng.integers(len(options)))]

    def whole(self, lo: int, hi: int) -> int:
        """A whole number in [lo, hi]."""
        return int(self.rng.integers(lo, hi + 1))

    def thickness(self) -> float:
        return self.u(*WALL_THICKNESS_RANGE_M)

    def point(self, x_lo: float, x_hi: float, y_lo: float = 0.0, y_hi: float = math.inf) -> tuple[float, float]:
        """A start or target in the given ranges, at least `margin_m` from the wall."""
        m = self.margin_m
        return (self.u(max(x_lo, m), min(x_hi, self.width_m - m)), self.u(max(y_lo, m), min(y_hi, self.height_m - m)))

    def heading(self, start: tuple[float, float], target: tuple[float, float]) -> float:
        """Towards the target (to the nearest 45°) half the time, else any multiple of 45°."""
        if self.chance(0.5) and start != target:
            bearing = math.degrees(math.atan2(target[0] - start[0], target[1] - start[1]))
            return float(compass_deg(round(bearing / 45.0) * 45))
        return float(self.whole(0, 7) * 45)

    def box(self, cx: float, cy: float, w: float, h: float, known: bool, role: str) -> _Box:
        return _Box(round(cx - w / 2, 6), round(cx + w / 2, 6), round(cy - h / 2, 6), round(cy + h / 2, 6), known, role)

    def fits(
        self, box: _Box | _Post, boxes: Sequence[_Box | _Post], ends: Sequence[tuple[float, float]], gap_m: float = 0.02
    ) -> bool:
        """On the arena, `gap_m` from the other boxes (and posts), and clear of the start and the target."""
        return (
            box.on_arena(self.width_m, self.height_m)
            and all(box.gap_to(b) >= gap_m for b in boxes)
            and all(box.distance_to(*p) > self.clear_m for p in ends)
        )

    def scatter(
        self,
        boxes: list[_Box],
        n: int,
        ends: Sequence[tuple[float, float]],
        unknown_p: float,
        role: str,
        sizes: Sequence[tuple[float, float]] = SEED_BOX_SIZES_M,
        x_range: tuple[float, float] | None = None,
        near_line_p: float = 0.6,
    ) -> None:
        """Add up to `n` boxes, most near the line from ends[0] to ends[1], the rest anywhere in x_range."""
        x_lo, x_hi = x_range or (0.0, self.width_m)
        (ax, ay), (bx, by) = ends[0], ends[-1]
        for _ in range(n):
            for _ in range(30):
                w, h = self.pick(sizes)
                if self.chance(near_line_p):
                    t = self.rng.uniform(0.2, 0.8)
                    cx = ax + t * (bx - ax) + self.rng.normal(0.0, 0.12)
                    cy = ay + t * (by - ay) + self.rng.normal(0.0, 0.2)
                else:
                    cx = self.rng.uniform(x_lo + w / 2, max(x_hi - w / 2, x_lo + w / 2))
                    cy = self.rng.uniform(h / 2, self.height_m - h / 2)
                box = self.box(round(cx, 3), round(cy, 3), w, h, not self.chance(unknown_p), role)
                if self.fits(box, boxes, ends):
                    boxes.append(box)
                    break

    def known_path(
        self, layout_boxes: Sequence[_Box], start: tuple[float, float], target: tuple[float, float]
    ) -> PlanResult:
        """The optimum on the known boxes so far; _Redraw when there is none."""
        grid = OccupancyGrid(self.width_m, self.height_m, self.config)
        for b in layout_boxes:
            if b.known:
                grid.add_box((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2, b.x1 - b.x0, b.y1 - b.y0)
        try:
            return plan(grid, start, target)
        except NoPathError as exc:
            raise _Redraw(str(exc)) from None

    def across_path(
        self, waypoints: Sequence[tuple[float, float]], fraction: float, w: float, h: float, role: str
    ) -> _Box:
        """An unknown box centred near the point `fraction` of the way along the path, across it."""
        pts = np.asarray(waypoints, dtype=np.float64)
        seg = np.hypot(*np.diff(pts, axis=0).T)
        along = fraction * float(seg.sum())
        i = int(np.searchsorted(np.cumsum(seg), along))
        i = min(i, len(seg) - 1)
        before = float(seg[:i].sum())
        direction = (pts[i + 1] - pts[i]) / max(seg[i], 1e-12)
        p = pts[i] + direction * (along - before)
        normal = np.array([-direction[1], direction[0]])
        # Off the path by at most 0.3 of the box's half side: the path still runs through it.
        c = p + normal * self.rng.uniform(-0.3, 0.3) * min(w, h) / 2
        return self.box(round(float(c[0]), 3), round(float(c[1]), 3), w, h, False, role)

    def beside(
        self,
        p: tuple[float, float],
        bearing_deg: float,
        clearance_m: float,
        w: float,
        h: float,
        role: str,
        known: bool = False,
    ) -> _Box:
        """A box (unknown by default) in direction `bearing_deg` (0° = +y, clockwise) from p, its
        nearest face `clearance_m` from p."""
        ux, uy = math.sin(math.radians(bearing_deg)), math.cos(math.radians(bearing_deg))

        def gap(r: float) -> float:
            return self.box(p[0] + r * ux, p[1] + r * uy, w, h, False, role).distance_to(*p)

        lo, hi = 0.0, clearance_m + math.hypot(w, h)
        for _ in range(40):  # the gap grows with r: bisect for the clearance
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if gap(mid) < clearance_m else (lo, mid)
        r = round(hi + 0.0005, 3)
        return self.box(round(p[0] + r * ux, 3), round(p[1] + r * uy, 3), w, h, known, role)


def _wall(x0: float, x1: float, y0: float, y1: float, known: bool, role: str, shape: str = "wall") -> _Box:
    """An axis-aligned wall by its edges (shape "box" for a block written as a box)."""
    return _Box(round(x0, 6), round(x1, 6), round(y0, 6), round(y1, 6), known, role, shape)
