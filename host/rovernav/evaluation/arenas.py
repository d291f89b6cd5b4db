"""`rovernav arenas`: scenario files drawn from families of arenas that real rooms and the seed's
tests contain, each labelled with its family, a difficulty and whether it can be solved.

    arenas = generate_arenas(200, seed=1)              # list[GeneratedArena], the families cycled
    write_arenas(arenas, Path("out/arenas"))           # arena-0001-scattered.toml ... index.json, index.csv
    write_gallery(arenas[:12], Path("out/arenas/gallery.png"))

Every file is an ordinary scenario (rovernav.scenario, TOML version 1) with an extra
[generated] table: family, seed, index, solvable, the narrow_passage family's passage_width_m,
and [generated.difficulty] (the metrics below, a score and a band).

Families: FAMILIES holds (name, one-line description) pairs, defined with their draw functions in
`_FAMILY_LIST` (`rovernav arenas --help` prints them). Arena i, counted from 1, is of family
number (i − 1) mod F of the F families asked for, so any count ≥ F covers all of them.

Geometry
    Arenas are 2.0-3.0 m × 1.5-2.2 m (the seed's is 2.36 × 1.75 m), so that missions stay as
    short as the seed's. Obstacles: axis-aligned boxes (the seed's box sizes, blocks up to
    0.25 m), walls ([[walls]]: dividers, corridor walls, traps and enclosures, 0.04-0.06 m thick,
    the traps' also 0.1 or 0.2 m; along x or y, but for wall_gap's door leaf, open at 70-90°) and
    round posts ([[posts]], 0.05-0.10 m across, in the clutter family). Every length that depends on the rover
    comes from PlannerConfig: the planner keeps the rover's centre `inflation_m` (robot radius +
    sonar margin, 0.17 m) from obstacles and walls, so a passage up to 2 × inflation_m wide is
    closed, and one up to a cell (0.03 m) wider is open or closed depending on where the cell
    centres fall.
    Each family is drawn in one frame (start on the left, target on the right) and then mirrored
    left-right and/or top-bottom at random. Lengths are drawn on a millimetre grid.

Constraints, checked on the scenario as parsed back from its own text
    every box, wall and post lies on the arena; start and target are free on the grid of every obstacle
    (OccupancyGrid.from_scenario(..., all_obstacles=True).is_free); `solvable` is whether
    `plan` (A*, default PlannerConfig) finds a path with every obstacle known; the unreachable
    family must be unsolvable because obstacles enclose the target (plan raises Unreachable with
    both ends free), the narrow_passage family may be either, every other family must be
    solvable. A draw that breaks a constraint is drawn again from the same stream, up to
    MAX_TRIES times, then GenerationFailed.

Difficulty metrics ([generated.difficulty]), in the spirit of BARN (Perille et al., 2020)
    The path is the clairvoyant optimum: A*'s simplified waypoints with every obstacle known,
    sampled every grid cell (0.03 m) with both ends included; for an unsolvable arena, the
    straight segment from start to target. Distances are exact, to the boxes, walls, posts and the
    arena's wall.
    closest_obstacle_m          the smallest distance from a path point to an obstacle or the wall
    mean_clearance_m            the mean of that distance over the path points
    dispersion                  from each path point, 16 rays (every 22.5°) of RAY_LENGTH_M,
                                sampled every RAY_STEP_M: the number of switches between free and
                                occupied (inside an obstacle) along them, summed over the rays, averaged
                                over the path points; a ray ends at the arena's wall, which is not
                                counted (open floor: 0; a ray across a thin wall: 2)
    characteristic_dimension_m  from each path point, the free length of the 8 lines through it
                                (the two opposite rays to the first obstacle or wall, each capped at
                                RAY_LENGTH_M); the shortest of the 8 is the width of the space the
                                point stands in; averaged over the path points
    narrowest_dimension_m       the smallest of those widths along the path: the tightest place it
                                passes (about a passage's width; 0 when unsolvable)
    optimal_length_m            the optimum's length (absent when unsolvable)
    detour_ratio                optimal_length_m / straight distance start-target (absent when
                                unsolvable; 1 when they are under a millimetre apart)
    known_path_blocked          the path A* plans on the known obstacles alone enters a cell the
                                grid of every obstacle inflates: the rover must find an unknown
                                obstacle with its sonar and replan (false when the known obstacles
                                alone already leave no path)
    score = 0.15 narrow + 0.15 pinch + 0.10 tight + 0.15 clutter + 0.25 detour + 0.20 surprise
        (SCORE_WEIGHTS), each term in [0, 1], higher is harder:
        narrow  = clip((CD_OPEN_M − characteristic_dimension_m) / (CD_OPEN_M − 2 inflation), 0, 1)
        pinch   = clip((PINCH_OPEN_M − narrowest_dimension_m) / (PINCH_OPEN_M − 2 inflation), 0, 1)
        tight   = clip((CLEARANCE_OPEN_M − mean_clearance_m) / (CLEARANCE_OPEN_M − inflation), 0, 1)
        clutter = clip(dispersion / DISPERSION_DENSE, 0, 1)
        detour  = clip((detour_ratio − 1) / DETOUR_LONG, 0, 1), 1 when unsolvable
        surprise = 1 when known_path_blocked, else 0
    band: "easy" below BAND_MEDIUM (0.45), "hard" from BAND_HARD (0.65), "medium" between: over the
        600 arenas of seeds 1-3, about a third in each. A score compares arenas; it predicts no
        particular outcome (start_at_target is nearly always easy, trap_u and unreachable hard).

Determinism
    Arena i draws from numpy's PCG64 seeded with SeedSequence([seed, i]): the same seed, index
    and family give the same text byte for byte, whatever the count; another seed draws other
    arenas.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import heapq
import io
import json
import math
import re
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import cv2
import numpy as np

from ..angles import compass_deg
from ..errors import InputError, PlanningError
from ..files import write_atomic
from ..validate import output_file
from ..planning import NoPathError, OccupancyGrid, PlannerConfig, PlanResult, Unreachable, plan
from ..scenario import Scenario, parse_scenario

MAX_COUNT = 100_000
MAX_TRIES = 400                      # draws of one arena before GenerationFailed
GALLERY_COUNT = 12                   # arenas on the contact sheet (3 rows of 4)

ARENA_WIDTH_RANGE_M = (2.0, 3.0)
ARENA_HEIGHT_RANGE_M = (1.5, 2.2)
WALL_THICKNESS_RANGE_M = (0.04, 0.06)
# The seed's boxes: 0.08 m (small obstacles), 0.15, 0.18, 0.25, 0.30 × 0.15 (out-and-back), 0.20 (Fig. 4.8).
SEED_BOX_SIZES_M = ((0.08, 0.08), (0.15, 0.15), (0.18, 0.18), (0.20, 0.20), (0.25, 0.25), (0.30, 0.15),
                    (0.15, 0.30))
POST_DIAMETERS_M = (0.05, 0.06, 0.08, 0.10)   # table legs, pipes, pillars: the clutter family's posts
KEEP_CLEAR_M = 0.03                  # beyond the inflation: a box keeps the start's and target's cells free
END_MARGIN_M = 0.06                  # beyond the inflation: start and target from the arena's wall
NARROW_EXTRA_M = 0.06                # narrow passages: 2 × inflation to 2 × inflation + this
START_AT_TARGET_RANGE_M = (0.021, 0.049)

RAY_COUNT = 16
RAY_LENGTH_M = 1.0
RAY_STEP_M = 0.01
CD_OPEN_M = 1.6                      # a characteristic dimension this wide is open floor
PINCH_OPEN_M = 1.0                   # a narrowest place this wide is no squeeze
CLEARANCE_OPEN_M = 0.45              # a mean clearance this large is open floor
DISPERSION_DENSE = 15.0              # this many switches is dense clutter
DETOUR_LONG = 0.5                    # a path 50 % longer than the straight line is a long detour
SCORE_WEIGHTS = {"narrow": 0.15, "pinch": 0.15, "tight": 0.10, "clutter": 0.15, "detour": 0.25, "surprise": 0.20}
# Over the 600 arenas of seeds 1-3 the score's tertiles fell at 0.46 and 0.64.
BAND_MEDIUM = 0.45
BAND_HARD = 0.65

INDEX_FIELDS = ("file", "name", "index", "seed", "family", "solvable", "band", "score", "closest_obstacle_m",
                "mean_clearance_m", "dispersion", "characteristic_dimension_m", "optimal_length_m",
                "detour_ratio", "known_path_blocked", "passage_width_m", "width_m", "height_m", "mission",
                "known_obstacles", "unknown_obstacles")

_ARENA_FILE = re.compile(r"^arena-\d{4,}-[a-z_]+\.toml$")


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
    shape: str = "box"          # or "wall"

    def distance_to(self, x_m: float, y_m: float) -> float:
        dx = max(self.x0 - x_m, 0.0, x_m - self.x1)
        dy = max(self.y0 - y_m, 0.0, y_m - self.y1)
        return math.hypot(dx, dy)

    def gap_to(self, other: "_Box | _Post") -> float:
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

    def gap_to(self, other: "_Box | _Post") -> float:
        if isinstance(other, _Post):
            return max(math.hypot(other.x - self.x, other.y - self.y) - self.r - other.r, 0.0)
        return max(other.distance_to(self.x, self.y) - self.r, 0.0)

    def on_arena(self, width_m: float, height_m: float) -> bool:
        return (self.x - self.r >= 0 and self.y - self.r >= 0 and self.x + self.r <= width_m
                and self.y + self.r <= height_m)


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
    boxes: list[_Box]                           # boxes and axis-aligned walls
    note: str                                   # what this arena is, for the description
    kind: str = "reach"
    trips: int = 1
    passage_width_m: float | None = None
    segs: list[_Seg] = dataclasses.field(default_factory=list)     # walls at an angle
    posts: list[_Post] = dataclasses.field(default_factory=list)


class _Draw:
    """The random choices of one draw: numbers on a millimetre grid from the arena's stream."""

    def __init__(self, rng: np.random.Generator, config: PlannerConfig):
        self.rng = rng
        self.config = config
        self.inflation_m = config.inflation_m
        self.width_m = self.u(*ARENA_WIDTH_RANGE_M, step_m=0.01)
        self.height_m = self.u(*ARENA_HEIGHT_RANGE_M, step_m=0.01)
        self.margin_m = self.inflation_m + END_MARGIN_M      # start and target from the wall
        self.clear_m = self.inflation_m + KEEP_CLEAR_M       # a box from the start and the target

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
        return (self.u(max(x_lo, m), min(x_hi, self.width_m - m)),
                self.u(max(y_lo, m), min(y_hi, self.height_m - m)))

    def heading(self, start: tuple[float, float], target: tuple[float, float]) -> float:
        """Towards the target (to the nearest 45°) half the time, else any multiple of 45°."""
        if self.chance(0.5) and start != target:
            bearing = math.degrees(math.atan2(target[0] - start[0], target[1] - start[1]))
            return float(compass_deg(round(bearing / 45.0) * 45))
        return float(self.whole(0, 7) * 45)

    def box(self, cx: float, cy: float, w: float, h: float, known: bool, role: str) -> _Box:
        return _Box(round(cx - w / 2, 6), round(cx + w / 2, 6), round(cy - h / 2, 6), round(cy + h / 2, 6),
                    known, role)

    def fits(self, box: _Box | _Post, boxes: Sequence[_Box | _Post], ends: Sequence[tuple[float, float]],
             gap_m: float = 0.02) -> bool:
        """On the arena, `gap_m` from the other boxes (and posts), and clear of the start and the target."""
        return (box.on_arena(self.width_m, self.height_m)
                and all(box.gap_to(b) >= gap_m for b in boxes)
                and all(box.distance_to(*p) > self.clear_m for p in ends))

    def scatter(self, boxes: list[_Box], n: int, ends: Sequence[tuple[float, float]], unknown_p: float,
                role: str, sizes: Sequence[tuple[float, float]] = SEED_BOX_SIZES_M,
                x_range: tuple[float, float] | None = None, near_line_p: float = 0.6) -> None:
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

    def known_path(self, layout_boxes: Sequence[_Box], start: tuple[float, float],
                   target: tuple[float, float]) -> PlanResult:
        """The optimum on the known boxes so far; _Redraw when there is none."""
        grid = OccupancyGrid(self.width_m, self.height_m, self.config)
        for b in layout_boxes:
            if b.known:
                grid.add_box((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2, b.x1 - b.x0, b.y1 - b.y0)
        try:
            return plan(grid, start, target)
        except NoPathError as exc:
            raise _Redraw(str(exc)) from None

    def across_path(self, waypoints: Sequence[tuple[float, float]], fraction: float, w: float, h: float,
                    role: str) -> _Box:
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

    def beside(self, p: tuple[float, float], bearing_deg: float, clearance_m: float, w: float, h: float,
               role: str, known: bool = False) -> _Box:
        """A box (unknown by default) in direction `bearing_deg` (0° = +y, clockwise) from p, its
        nearest face `clearance_m` from p."""
        ux, uy = math.sin(math.radians(bearing_deg)), math.cos(math.radians(bearing_deg))

        def gap(r: float) -> float:
            return self.box(p[0] + r * ux, p[1] + r * uy, w, h, False, role).distance_to(*p)

        lo, hi = 0.0, clearance_m + math.hypot(w, h)
        for _ in range(40):   # the gap grows with r: bisect for the clearance
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if gap(mid) < clearance_m else (lo, mid)
        r = round(hi + 0.0005, 3)
        return self.box(round(p[0] + r * ux, 3), round(p[1] + r * uy, 3), w, h, known, role)


def _wall(x0: float, x1: float, y0: float, y1: float, known: bool, role: str, shape: str = "wall") -> _Box:
    """An axis-aligned wall by its edges (shape "box" for a block written as a box)."""
    return _Box(round(x0, 6), round(x1, 6), round(y0, 6), round(y1, 6), known, role, shape)


# --- the families, each drawn with the start on the left and the target on the right --------------

def _scattered(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.25 * W), d.point(0.75 * W, W)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(3, 7), (start, target), unknown_p=0.4, role="box", x_range=(0.2 * W, 0.85 * W))
    if len({b.known for b in boxes}) < 2:
        raise _Redraw("want known and unknown boxes")
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"{len(boxes)} boxes of the seed's sizes, some unknown")


def _divider(x0: float, x1: float, gap_lo: float, gap_hi: float, H: float, known: Sequence[bool],
             role: str, shape: str = "wall") -> list[_Box]:
    """A full-height wall from x0 to x1 with an opening from gap_lo to gap_hi [m]."""
    parts = []
    if gap_lo > 0:
        parts.append(_wall(x0, x1, 0.0, gap_lo, known[0], f"{role}, lower part", shape))
    if gap_hi < H:
        parts.append(_wall(x0, x1, gap_hi, H, known[-1], f"{role}, upper part", shape))
    return parts


def _wall_gap(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = d.thickness()
    x0 = d.u(0.4 * W, 0.6 * W - t)
    door = d.chance(0.4)
    gap = d.u(2 * inf + 0.12, 2 * inf + 0.40) + (t if door else 0.0)
    lo = d.u(0.1, H - gap - 0.1) if d.chance(0.8) else d.pick((0.0, round(H - gap, 3)))
    hi = round(lo + gap, 6)
    wall_known = d.chance(0.5)
    boxes = _divider(x0, x0 + t, lo, hi, H, (wall_known,), "divider")
    note = "a divider wall with a gap" + ("" if wall_known else " (the wall unknown)")
    segs: list[_Seg] = []
    keep_out: list[_Box] = []
    if door:
        # The door stands open on the target's side, hinged at one edge of the opening, at 70-90°
        # from the divider (a wall at an angle: its faces turn the sonar's echoes away).
        leaf = round(gap - t, 6)
        upper = d.chance(0.5)
        angle = math.radians(d.whole(70, 90))
        hinge = (x0 + t, hi - t / 2 if upper else lo + t / 2)
        tip = (hinge[0] + leaf * math.sin(angle), hinge[1] + (-1 if upper else 1) * leaf * math.cos(angle))
        leaf_known = wall_known and d.chance(0.3)
        segs.append(_Seg(round(hinge[0], 6), round(hinge[1], 6), round(tip[0], 6), round(tip[1], 6), t, leaf_known,
                         "door leaf, open"))
        # What the leaf covers, so that no box is scattered onto it.
        keep_out = [_Box(hinge[0] - t, tip[0] + t, min(hinge[1], tip[1]) - t, max(hinge[1], tip[1]) + t, True, "")]
        note = f"a divider wall with a door open at {round(math.degrees(angle))}°" + \
            ("" if wall_known else " (the wall unknown)") + ("" if leaf_known else ", the door leaf unknown")
    start = d.point(0, x0 - 0.3)
    target = d.point(x0 + t + (gap if door else 0.0) + 0.3, W)
    if d.chance(0.5):
        placed = boxes + keep_out
        d.scatter(placed, 1, (start, target), unknown_p=0.5, role="box", near_line_p=0.0)
        boxes += placed[len(boxes) + len(keep_out):]
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note, segs=segs)


def _corridor(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = d.thickness()
    inner = d.u(2 * inf + 0.08, 2 * inf + 0.26)
    length = d.u(0.7, min(1.3, W - 2 * (d.margin_m + 0.25)))
    x0 = d.u((W - length) / 2 - 0.15, (W - length) / 2 + 0.15)
    x0 = min(max(x0, d.margin_m + 0.2), W - length - d.margin_m - 0.2)
    yc = d.u(0.35 * H, 0.65 * H)
    y_lo, y_hi = round(yc - inner / 2, 6), round(yc + inner / 2, 6)
    boxes = [_wall(x0, x0 + length, y_lo - t, y_lo, d.chance(0.6), "corridor wall, lower"),
             _wall(x0, x0 + length, y_hi, y_hi + t, d.chance(0.6), "corridor wall, upper")]
    closed = d.chance(0.5)
    if closed:   # bulkheads from the corridor's mouth to the arena's wall: the corridor is the only way
        known = d.chance(0.7)
        boxes += [_wall(x0, x0 + t, 0.0, y_lo - t, known, "bulkhead, lower"),
                  _wall(x0, x0 + t, y_hi + t, H, known, "bulkhead, upper")]
    if inner - 0.08 >= 2 * inf + 0.06 and d.chance(0.4):
        bx = d.u(x0 + 0.2, x0 + length - 0.2)
        y0, y1 = (y_lo, y_lo + 0.08) if d.chance(0.5) else (y_hi - 0.08, y_hi)
        boxes.append(_wall(bx - 0.04, bx + 0.04, y0, y1, False, "box against a corridor wall", "box"))
    # Open, the ends face the mouths (the corridor is on the way); closed, they may be anywhere.
    reach = 0.4 if closed else 0.12
    start = d.point(0, x0 - 0.2, yc - reach, yc + reach)
    target = d.point(x0 + length + 0.2, W, yc - reach, yc + reach)
    unknown = all(not b.known for b in boxes[:2])
    note = ("a closed corridor (the only way through)" if closed else "an open corridor") + \
        (", its walls unknown" if unknown else ", some walls unknown" if not all(b.known for b in boxes) else "")
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note)


def _trap_thickness(d: _Draw) -> float:
    return d.pick((d.thickness(), 0.1, 0.2))


def _trap_l(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    t = _trap_thickness(d)
    back = d.u(0.5, min(0.9, H - 0.8))
    floor = d.u(0.4, 0.8)
    xc = d.u(max(0.5 * W, floor + 0.6), 0.65 * W)
    yc = d.u(0.35, H - back - 0.4)
    which = d.pick(("all", "back", "none"))     # what is unknown
    boxes = [_wall(xc, xc + t, yc - t, yc + back, which == "none", "L trap, back"),
             _wall(xc - floor, xc, yc - t, yc, which != "all", "L trap, floor")]
    # The dead end faces the start: the straight line runs into the inside corner.
    start = d.point(0, xc - floor - 0.1, yc + 0.1, yc + 0.6 * back)
    target = d.point(xc + t + 0.25, W, yc + 0.1, yc + 0.8 * back)
    note = "an L-shaped dead end facing the start" + \
        {"all": ", unknown", "back": ", its back unknown", "none": ""}[which]
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note)


def _trap_u(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = _trap_thickness(d)
    room = 2 * inf + 0.1     # a way round on either side
    inner = d.u(2 * inf + 0.06, min(2 * inf + 0.40, H - 2 * t - 2 * room))
    depth = d.u(0.35, 0.7)
    half = inner / 2 + t
    slack = (H - 2 * half - 2 * room) / 2
    yc = d.u(H / 2 - slack, H / 2 + slack)
    xb = d.u(max(0.5 * W, depth + 0.7), min(0.7 * W, W - t - 0.5))
    which = d.pick(("all", "back", "none"))
    y_lo, y_hi = round(yc - inner / 2, 6), round(yc + inner / 2, 6)
    boxes = [_wall(xb, xb + t, y_lo - t, y_hi + t, which == "none", "U trap, back"),
             _wall(xb - depth, xb, y_hi, y_hi + t, which != "all", "U trap, upper arm"),
             _wall(xb - depth, xb, y_lo - t, y_lo, which != "all", "U trap, lower arm")]
    start = d.point(0, xb - depth - 0.15, yc - 0.1, yc + 0.1)
    target = d.point(xb + t + 0.2, W, yc - 0.15, yc + 0.15)
    note = "a U-shaped dead end facing the start" + \
        {"all": ", unknown", "back": ", its back unknown", "none": ""}[which]
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note)


def _clutter(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.2 * W), d.point(0.8 * W, W)
    wanted = d.whole(12, 22)
    sizes = (0.05, 0.08, 0.08, 0.10, 0.12, 0.15)
    (ax, ay), (bx, by) = start, target
    across = np.array([ay - by, bx - ax]) / math.dist(start, target)
    grid = OccupancyGrid(W, H, d.config)
    items: list[_Box | _Post] = []
    post_p = d.pick((0.0, 0.3, 0.6))   # how many of them are round posts (table legs, pillars)
    for _ in range(8 * wanted):
        if len(items) == wanted:
            break
        w, h = d.pick(sizes), d.pick(sizes)
        post = d.chance(post_p)
        if post:
            w = h = d.pick(POST_DIAMETERS_M)
        if d.chance(0.7):   # in a band 0.9 m wide along the way
            along, off = d.rng.uniform(0.1, 0.9), d.rng.uniform(-0.45, 0.45)
            cx = round(ax + along * (bx - ax) + off * across[0], 3)
            cy = round(ay + along * (by - ay) + off * across[1], 3)
        else:
            cx, cy = d.u(0.15 * W + w / 2, 0.85 * W - w / 2), d.u(h / 2, H - h / 2)
        item = _Post(cx, cy, w / 2, d.chance(0.4), "clutter, post") if post else \
            d.box(cx, cy, w, h, d.chance(0.4), "clutter")
        if not d.fits(item, items, (start, target), gap_m=0.01):
            continue
        trial = grid.copy()
        if post:
            trial.add_post(cx, cy, w / 2)
        else:
            trial.add_box(cx, cy, w, h)
        try:   # keep it only if a way through remains
            plan(trial, start, target, simplify=False)
        except NoPathError:
            continue
        grid = trial
        items.append(item)
    if len(items) < 12 or len({b.known for b in items}) < 2:
        raise _Redraw("not dense enough")
    boxes = [b for b in items if isinstance(b, _Box)]
    posts = [b for b in items if isinstance(b, _Post)]
    what = f"{len(boxes)} small boxes" + (f" and {len(posts)} posts" if posts else "")
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"dense clutter: {what}, most unknown", posts=posts)


def _narrow_passage(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = d.thickness() if d.chance(0.5) else d.u(0.10, 0.25)
    x0 = d.u(0.4 * W, 0.6 * W - t)
    width = d.u(2 * inf, 2 * inf + NARROW_EXTRA_M)
    where = d.pick(("middle", "middle", "bottom", "top"))
    lo = {"middle": None, "bottom": 0.0, "top": round(H - width, 6)}[where]
    if lo is None:
        lo = d.u(0.25, H - width - 0.25)
    knowledge = d.pick(("known", "known", "unknown", "mixed"))
    known = {"known": (True, True), "unknown": (False, False), "mixed": (True, False)}[knowledge]
    role = "divider" if t <= WALL_THICKNESS_RANGE_M[1] else "block"
    boxes = _divider(x0, x0 + t, lo, round(lo + width, 6), H, known, role, "wall" if role == "divider" else "box")
    start = d.point(0, x0 - 0.3)
    target = d.point(x0 + t + 0.3, W)
    kind = "between the divider and the arena's wall" if where != "middle" else "in a divider"
    note = (f"a {width * 100:.1f} cm passage {kind} "
            f"({'known' if knowledge == 'known' else 'unknown' if knowledge == 'unknown' else 'half known'}); "
            f"the rover's limit is {2 * inf * 100:.0f} cm")
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note, passage_width_m=width)


def _unknown_on_path(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.25 * W), d.point(0.75 * W, W)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(2, 4), (start, target), unknown_p=0.0, role="box", near_line_p=0.4)
    path = d.known_path(boxes, start, target)
    if path.length_m < 0.9:
        raise _Redraw("too short a path")
    fractions = [d.rng.uniform(0.35, 0.65)] if d.chance(0.6) else [d.rng.uniform(0.25, 0.42),
                                                                  d.rng.uniform(0.58, 0.75)]
    big = SEED_BOX_SIZES_M[1:]
    for f in fractions:
        box = d.across_path(path.waypoints, f, *d.pick(big), role="unknown, across the known map's optimal path")
        if not d.fits(box, boxes, (start, target)):
            raise _Redraw("the box on the path does not fit")
        boxes.append(box)
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"{len(fractions)} unknown box{'es' if len(fractions) > 1 else ''} across the optimal path "
                   f"of the known map")


def _unknown_near(d: _Draw, at_start: bool) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.3 * W), d.point(0.7 * W, W)
    here, there = (start, target) if at_start else (target, start)
    towards = math.degrees(math.atan2(there[0] - here[0], there[1] - here[1]))
    boxes: list[_Box] = []
    which = "start" if at_start else "target"
    for i in range(1 if d.chance(0.6) else 2):
        bearing = towards + (d.rng.uniform(-90, 90) if i == 0 else d.rng.uniform(-180, 180))
        clearance = d.rng.uniform(d.clear_m, d.inflation_m + 0.15)
        box = d.beside(here, bearing, clearance, *d.pick(SEED_BOX_SIZES_M), role=f"unknown, beside the {which}")
        if not d.fits(box, boxes, (start, target)):
            raise _Redraw(f"the box beside the {which} does not fit")
        boxes.append(box)
    n_near = len(boxes)
    d.scatter(boxes, d.whole(1, 3), (start, target), unknown_p=0.0, role="box", near_line_p=0.5)
    boxes = boxes[:n_near] + [b for b in boxes[n_near:] if b.distance_to(*here) > 0.4]
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"{n_near} unknown box{'es' if n_near > 1 else ''} beside the {which}")


def _unknown_near_start(d: _Draw) -> _Layout:
    return _unknown_near(d, at_start=True)


def _unknown_near_target(d: _Draw) -> _Layout:
    return _unknown_near(d, at_start=False)


def _unknown_against_wall(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    m = d.margin_m
    # Start and target along the bottom wall, so that the optimum runs beside it.
    start = d.point(0, 0.25 * W, 0, m + 0.2)
    target = d.point(0.75 * W, W, 0, m + 0.2)
    w = d.u(0.10, 0.30)
    # Deep enough that its inflation reaches past the line between start and target.
    y_way = (start[1] + target[1]) / 2
    depth = d.u(max(0.08, y_way - d.inflation_m + 0.03), y_way + 0.1)
    cx = d.u(0.35 * W, 0.65 * W)
    boxes = [_wall(cx - w / 2, cx + w / 2, 0.0, depth, False, "unknown, against the wall on the way", "box")]
    for _ in range(d.whole(0, 2)):
        w2, h2 = d.pick(SEED_BOX_SIZES_M)
        side = d.pick(("left", "right", "top", "top", "corner"))
        if side == "left":
            box = d.box(w2 / 2, d.u(h2 / 2, H - h2 / 2), w2, h2, False, "unknown, against the left wall")
        elif side == "right":
            box = d.box(W - w2 / 2, d.u(h2 / 2, H - h2 / 2), w2, h2, False, "unknown, against the right wall")
        elif side == "top":
            box = d.box(d.u(w2 / 2, W - w2 / 2), H - h2 / 2, w2, h2, False, "unknown, against the top wall")
        else:
            box = d.box(W - w2 / 2, H - h2 / 2, w2, h2, False, "unknown, in a corner")
        if d.fits(box, boxes, (start, target)):
            boxes.append(box)
    d.scatter(boxes, d.whole(0, 2), (start, target), unknown_p=0.0, role="box", near_line_p=0.0)
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"{sum(not b.known for b in boxes)} unknown boxes against the arena's walls, "
                   f"one beside the way")


def _out_and_back(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start = d.point(0, 0.25 * W, 0, 0.3 * H)
    target = d.point(0.75 * W, W, 0.7 * H, H)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(1, 3), (start, target), unknown_p=0.0, role="box")
    n_known = len(boxes)
    if d.chance(0.6):
        path = d.known_path(boxes, start, target)
        box = d.across_path(path.waypoints, d.rng.uniform(0.3, 0.7), *d.pick(SEED_BOX_SIZES_M[1:]),
                            role="unknown, across the known map's optimal path")
        if d.fits(box, boxes, (start, target)):
            boxes.append(box)
    d.scatter(boxes, d.whole(1, 2), (start, target), unknown_p=1.0, role="unknown box")
    if len(boxes) == n_known:
        raise _Redraw("no unknown box")
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"out to the target and back, {n_known} known and {len(boxes) - n_known} unknown boxes",
                   kind="out-and-back", trips=1)


def _unreachable(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = d.thickness()
    start = d.point(0, 0.3 * W)
    variant = d.pick(("ring", "ring", "corner", "divider"))
    if variant == "ring":
        ax, ay = d.u(inf + 0.04, inf + 0.14), d.u(inf + 0.04, inf + 0.14)   # inside half sizes
        cx = d.u(0.6 * W, W - ax - t - 0.05)
        cy = d.u(ay + t + 0.05, H - ay - t - 0.05)
        target = (d.u(cx - (ax - d.clear_m), cx + (ax - d.clear_m)), d.u(cy - (ay - d.clear_m), cy + (ay - d.clear_m)))
        sides = [d.chance(0.5) for _ in range(4)]
        boxes = [_wall(cx - ax - t, cx - ax, cy - ay - t, cy + ay + t, sides[0], "enclosure, left"),
                 _wall(cx + ax, cx + ax + t, cy - ay - t, cy + ay + t, sides[1], "enclosure, right"),
                 _wall(cx - ax, cx + ax, cy - ay - t, cy - ay, sides[2], "enclosure, bottom"),
                 _wall(cx - ax, cx + ax, cy + ay, cy + ay + t, sides[3], "enclosure, top")]
        note = "the target inside a closed box of walls"
    elif variant == "corner":
        c = d.clear_m
        lx, ly = d.u(2 * c + 0.01, 2 * c + 0.25), d.u(2 * c + 0.01, 2 * c + 0.25)   # inside sizes
        known = d.chance(0.5)
        boxes = [_wall(W - lx - t, W - lx, H - ly - t, H, known, "corner enclosure, side"),
                 _wall(W - lx, W, H - ly - t, H - ly, d.chance(0.5), "corner enclosure, front")]
        target = (d.u(W - lx + c, W - c), d.u(H - ly + c, H - c))
        note = "the target walled into a corner"
    else:
        x0 = d.u(0.45 * W, 0.65 * W)
        boxes = [_wall(x0, x0 + t, 0.0, H, d.chance(0.5), "divider without a gap")]
        target = d.point(x0 + t + 0.25, W)
        note = "a divider wall with no gap between start and target"
    unknown = sum(not b.known for b in boxes)
    note += f" ({unknown} of {len(boxes)} walls unknown)" if unknown else ""
    d.scatter(boxes, d.whole(0, 2), (start, target), unknown_p=0.5, role="box", near_line_p=0.0,
              x_range=(0.0, 0.5 * W))
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note)


def _start_at_target(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start = d.point(0, W)
    r = d.rng.uniform(*START_AT_TARGET_RANGE_M)
    a = d.rng.uniform(0, 2 * math.pi)
    target = (round(start[0] + r * math.sin(a), 3), round(start[1] + r * math.cos(a), 3))
    if not 0.02 <= math.dist(start, target) <= 0.05:
        raise _Redraw("start and target not 2-5 cm apart after rounding")
    boxes: list[_Box] = []
    if d.chance(0.5):
        boxes.append(d.beside(start, d.rng.uniform(-180, 180), d.rng.uniform(d.clear_m + 0.05, d.clear_m + 0.3),
                              *d.pick(SEED_BOX_SIZES_M), role="box near the start", known=d.chance(0.5)))
        if not d.fits(boxes[0], [], (start, target)):
            raise _Redraw("the box near the start does not fit")
    d.scatter(boxes, d.whole(1, 3), (start, target), unknown_p=0.5, role="box", near_line_p=0.0)
    return _Layout(W, H, start, float(d.whole(0, 7) * 45), target, boxes,
                   f"the target {math.dist(start, target) * 100:.1f} cm from the start")


# --- cellular: BARN's worlds, scaled to this rover -------------------------------------------------

#: BARN (Perille et al., 2020) draws its 300 worlds on a grid of 0.15 m cells for a Jackal
#: (0.51 x 0.43 m): random fill, then cellular-automaton smoothing, start and goal on the centre
#: line, and keeps only a world with a way through. Scaled by 0.56 so that its robot becomes
#: ours, a cell is 0.084 m.
CELLULAR_CELL_M = 0.084
CELLULAR_WIDTH_RANGE_M = (2.5, 4.0)
CELLULAR_HEIGHT_RANGE_M = (1.8, 3.0)
CELLULAR_FILL_RANGE = (0.10, 0.30)      # BARN's initial fill, the share of cells occupied
CELLULAR_SMOOTHING = (0, 4)             # BARN's smoothing iterations
CELLULAR_BOXES = (8, 120)               # boxes (merged cells) an arena may hold
CELLULAR_FIELDS = 6                     # fields drawn with one fill and smoothing before one is carved


def _way_through(occ: np.ndarray, need_cells: float) -> bool:
    """Whether the middle of the field's left column and of its right column are joined through
    cells more than `need_cells` (centre to centre) from every occupied cell (outside the field
    is free floor)."""
    ny, nx = occ.shape
    free = np.pad((~occ).astype(np.uint8), 1, constant_values=1)
    room = cv2.distanceTransform(free, cv2.DIST_L2, 5)[1:-1, 1:-1] > need_cells
    _, labels = cv2.connectedComponents(room.astype(np.uint8), connectivity=4)
    a, b = (ny // 2, 0), (ny // 2, nx - 1)
    return bool(room[a] and room[b] and labels[a] == labels[b])


def _cheapest_way(cost: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """The cells (row, column) of the cheapest 4-connected way from start to goal (Dijkstra on
    weighted cells: planning.astar_cells searches a free/blocked grid, not costs)."""
    ny, nx = cost.shape
    best = np.full(cost.shape, np.inf)
    best[start] = 0.0
    came: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(0.0, start)]
    while heap:
        dist, here = heapq.heappop(heap)
        if here == goal:
            break
        if dist > best[here]:
            continue
        y, x = here
        for v, u in ((y + 1, x), (y - 1, x), (y, x + 1), (y, x - 1)):
            if 0 <= v < ny and 0 <= u < nx and dist + cost[v, u] < best[v, u]:
                best[v, u] = dist + cost[v, u]
                came[(v, u)] = here
                heapq.heappush(heap, (float(best[v, u]), (v, u)))
    way = [goal]
    while way[-1] != start:
        way.append(came[way[-1]])
    return way[::-1]


def _carve(occ: np.ndarray, need_cells: float, rng: np.random.Generator) -> int:
    """Frees a way from the middle of the field's left column to the middle of its right one,
    through one or two cells drawn at random between (so that it winds, as a way through a
    cave does): the cheapest way, where an occupied cell costs 40 and a free one 1, so that it
    follows the gaps there are, widened to a rover's width (the occupied cells within
    `need_cells`, rounded up, of it). Returns how many cells it freed."""
    ny, nx = occ.shape
    cost = 1.0 + 40.0 * occ
    k = int(rng.integers(1, 3))
    inner = [(int(rng.integers(ny // 5, ny - ny // 5)), int((i + 1) * nx / (k + 1))) for i in range(k)]
    points = [(ny // 2, 0), *inner, (ny // 2, nx - 1)]
    way = np.zeros(occ.shape, np.uint8)
    for a, b in zip(points, points[1:]):
        for cell in _cheapest_way(cost, a, b):
            way[cell] = 1
    freed = 0
    for r in (math.ceil(need_cells), math.ceil(need_cells) + 1):
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        wide = cv2.dilate(way, disk) > 0
        freed += int((occ & wide).sum())
        occ[wide] = False
        if _way_through(occ, need_cells):
            break
    return freed


def _smooth(occ: np.ndarray) -> np.ndarray:
    """One cellular-automaton step (BARN's, the cave rule): a cell with 5 or more occupied
    neighbours of its 8 becomes occupied, one with 3 or fewer becomes free, else it stays (outside
    the grid counts as free floor)."""
    padded = np.pad(occ.astype(np.int8), 1)
    n = sum(padded[1 + dy:padded.shape[0] - 1 + dy, 1 + dx:padded.shape[1] - 1 + dx]
            for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dx, dy) != (0, 0))
    return np.where(n >= 5, True, np.where(n <= 3, False, occ))


def _cell_boxes(occ: np.ndarray, x0: float, y0: float, c: float) -> list[tuple[float, float, float, float]]:
    """The occupied cells as few boxes (x0, x1, y0, y1): each row's runs, merged with the same run
    of the rows above."""
    open_runs: dict[tuple[int, int], list[int]] = {}   # (first column, last column) -> [first row, last row]
    done = []
    for row in range(occ.shape[0]):
        runs, col = [], 0
        while col < occ.shape[1]:
            if occ[row, col]:
                end = col
                while end + 1 < occ.shape[1] and occ[row, end + 1]:
                    end += 1
                runs.append((col, end))
                col = end + 1
            else:
                col += 1
        for key in list(open_runs):
            if key not in runs:
                done.append((key, open_runs.pop(key)))
        for key in runs:
            open_runs.setdefault(key, [row, row])[1] = row
    done += list(open_runs.items())
    return [(round(x0 + a * c, 6), round(x0 + (b + 1) * c, 6), round(y0 + r0 * c, 6), round(y0 + (r1 + 1) * c, 6))
            for (a, b), (r0, r1) in done]


def _cellular(d: _Draw) -> _Layout:
    c = CELLULAR_CELL_M
    W = d.width_m = d.u(*CELLULAR_WIDTH_RANGE_M, step_m=0.01)
    H = d.height_m = d.u(*CELLULAR_HEIGHT_RANGE_M, step_m=0.01)
    fill, smoothing = d.u(*CELLULAR_FILL_RANGE, step_m=0.01), d.whole(*CELLULAR_SMOOTHING)
    # The obstacle field between a start strip and a target strip, as BARN's lies between its
    # start and goal; both on the centre line.
    strip = d.margin_m + 0.1
    nx, ny = int((W - 2 * strip) / c), int(H / c)
    x0, y0 = (W - nx * c) / 2, (H - ny * c) / 2
    start, target = (round(d.margin_m, 3), round(H / 2, 3)), (round(W - d.margin_m, 3), round(H / 2, 3))
    # A way through for the rover: the cells its centre may stand on are those further than its
    # inflation from every occupied cell (centre to the occupied cell's edge), and the start's
    # side and the target's must be joined through them. BARN keeps only worlds with a way
    # through: a few fields are drawn with these numbers, and if none has one (a dense field for
    # a rover whose inflation spans 4 cells seldom does), a way is carved through the last along
    # a wandering line, so that the densities stay as drawn.
    need = d.inflation_m / c + 0.5
    for attempt in range(CELLULAR_FIELDS):
        occ = d.rng.random((ny, nx)) < fill
        for _ in range(smoothing):
            occ = _smooth(occ)
        if _way_through(occ, need):
            carved = 0
            break
    else:
        carved = _carve(occ, need, d.rng)
        if not _way_through(occ, need):
            raise _Redraw("no way through after carving")
    boxes = [_Box(bx0, bx1, by0, by1, False, "cell") for bx0, bx1, by0, by1 in _cell_boxes(occ, x0, y0, c)]
    if not CELLULAR_BOXES[0] <= len(boxes) <= CELLULAR_BOXES[1]:
        raise _Redraw(f"{len(boxes)} boxes")
    return _Layout(W, H, start, d.heading(start, target), target, boxes,
                   f"BARN-style cellular world: fill {fill:.2f}, {smoothing} smoothing steps, {len(boxes)} boxes "
                   f"({int(occ.sum())} cells of {c * 100:.1f} cm), every one unknown"
                   + (f"; {carved} cells carved for a way through" if carved else ""))


@dataclasses.dataclass(frozen=True)
class _Family:
    name: str
    description: str
    draw: Callable[[_Draw], _Layout]
    expects: str          # "solvable", "unsolvable" or "either"


_FAMILY_LIST = (
    _Family("scattered", "3-7 boxes of the seed's sizes near the way, some unknown", _scattered, "solvable"),
    _Family("wall_gap", "a full-height divider wall with a gap or a door open at 70-90°; the wall or the door "
                        "leaf often unknown", _wall_gap, "solvable"),
    _Family("corridor", "a corridor 0.42-0.60 m wide, open or the only way through; some walls unknown",
            _corridor, "solvable"),
    _Family("trap_l", "an L-shaped dead end facing the start, often unknown", _trap_l, "solvable"),
    _Family("trap_u", "a U-shaped dead end facing the start (the seed's large obstacles), often unknown",
            _trap_u, "solvable"),
    _Family("clutter", "12-22 small boxes and round posts, most unknown, most along the way, as dense as "
                       "leaves a way", _clutter, "solvable"),
    _Family("narrow_passage", "the only passage 2 × inflation to 2 × inflation + 6 cm wide; solvable or not "
                              "by where the grid's cells fall", _narrow_passage, "either"),
    _Family("unknown_on_path", "unknown boxes across the optimal path of the known map", _unknown_on_path,
            "solvable"),
    _Family("unknown_near_start", "an unknown box just beyond the inflation from the start",
            _unknown_near_start, "solvable"),
    _Family("unknown_near_target", "an unknown box just beyond the inflation from the target",
            _unknown_near_target, "solvable"),
    _Family("unknown_against_wall", "unknown boxes flush against the arena's walls, one beside the way",
            _unknown_against_wall, "solvable"),
    _Family("out_and_back", "out to the target and back (one trip) past known and unknown boxes",
            _out_and_back, "solvable"),
    _Family("unreachable", "the target enclosed (free, but walled in): the answer is 'unreachable'",
            _unreachable, "unsolvable"),
    _Family("start_at_target", "the target 2-5 cm from the start", _start_at_target, "solvable"),
)
#: Families drawn only when asked for by name (--families): the default cycle, and so the arenas
#: of every seed drawn before they existed, stay as they were.
_EXTRA_FAMILY_LIST = (
    _Family("cellular", "BARN's worlds scaled to this rover: 2.5-4 x 1.8-3 m, cells of 8.4 cm filled at random "
                        "(10-30 %) and smoothed 0-4 times by a cellular automaton, every box "
                        "unknown; a world without a way through is drawn again (by name only)", _cellular, "solvable"),
)
FAMILIES: tuple[tuple[str, str], ...] = tuple((f.name, f.description) for f in _FAMILY_LIST + _EXTRA_FAMILY_LIST)
FAMILY_NAMES: tuple[str, ...] = tuple(f.name for f in _FAMILY_LIST)   # the default cycle
ALL_FAMILY_NAMES: tuple[str, ...] = FAMILY_NAMES + tuple(f.name for f in _EXTRA_FAMILY_LIST)
_BY_NAME = {f.name: f for f in _FAMILY_LIST + _EXTRA_FAMILY_LIST}


# --- from a layout to a scenario file ------------------------------------------------------------

def _mirror(layout: _Layout, flip_x: bool, flip_y: bool) -> _Layout:
    """The layout mirrored left-right and/or top-bottom (the heading follows)."""
    W, H = layout.width_m, layout.height_m

    def fx(x: float) -> float:
        return round(W - x, 6) if flip_x else x

    def fy(y: float) -> float:
        return round(H - y, 6) if flip_y else y

    swaps = ({"left": "right", "right": "left"} if flip_x else {}) | \
        ({"lower": "upper", "upper": "lower", "bottom": "top", "top": "bottom"} if flip_y else {})

    def role(text: str) -> str:
        return re.sub(r"[a-z]+", lambda m: swaps.get(m.group(0), m.group(0)), text)

    boxes = [_Box(*sorted((fx(b.x0), fx(b.x1))), *sorted((fy(b.y0), fy(b.y1))), b.known, role(b.role), b.shape)
             for b in layout.boxes]
    segs = [_Seg(fx(w.x0), fy(w.y0), fx(w.x1), fy(w.y1), w.thickness, w.known, role(w.role)) for w in layout.segs]
    posts = [_Post(fx(p.x), fy(p.y), p.r, p.known, role(p.role)) for p in layout.posts]
    heading = layout.heading_deg
    heading = -heading if flip_x else heading
    heading = 180.0 - heading if flip_y else heading
    return dataclasses.replace(layout, start=(fx(layout.start[0]), fy(layout.start[1])),
                               target=(fx(layout.target[0]), fy(layout.target[1])), boxes=boxes, segs=segs, posts=posts,
                               heading_deg=compass_deg(heading))


def _num(value: float) -> str:
    """A TOML float to 0.1 mm (or 1e-4), never -0.0."""
    return repr(round(float(value), 4) + 0.0)


def _toml_text(name: str, layout: _Layout, family: str, seed: int, index: int,
               generated: dict[str, Any] | None) -> str:
    """The scenario file; without `generated`, the draft that is checked and measured."""
    out = [f"# Generated by `rovernav arenas --seed {seed}`: arena {index}, family {family}.",
           f"# {layout.note}.",
           f"name = {json.dumps(name)}",
           "version = 1",
           f"description = {json.dumps(f'{family}: {layout.note}')}",
           "",
           "[arena]",
           f"width_m = {_num(layout.width_m)}",
           f"height_m = {_num(layout.height_m)}",
           "",
           "[start]",
           f"x_m = {_num(layout.start[0])}",
           f"y_m = {_num(layout.start[1])}",
           f"heading_deg = {_num(layout.heading_deg)}",
           "",
           "[target]",
           f"x_m = {_num(layout.target[0])}",
           f"y_m = {_num(layout.target[1])}",
           "",
           "[mission]",
           f"kind = {json.dumps(layout.kind)}",
           f"trips = {layout.trips}",
           ""]
    if generated is not None:
        out += ["[generated]",
                f"family = {json.dumps(generated['family'])}",
                f"seed = {generated['seed']}",
                f"index = {generated['index']}",
                f"solvable = {'true' if generated['solvable'] else 'false'}"]
        if "passage_width_m" in generated:
            out.append(f"passage_width_m = {_num(generated['passage_width_m'])}")
        out += ["", "[generated.difficulty]"]
        for key, value in generated["difficulty"].items():
            if isinstance(value, bool):
                out.append(f"{key} = {'true' if value else 'false'}")
            elif isinstance(value, str):
                out.append(f"{key} = {json.dumps(value)}")
            else:
                out.append(f"{key} = {_num(value)}")
        out.append("")
    for b in layout.boxes:
        if b.shape == "wall":
            continue
        out += [f"[[obstacles]]   # {b.role}",
                f"x_m = {_num((b.x0 + b.x1) / 2)}",
                f"y_m = {_num((b.y0 + b.y1) / 2)}",
                f"w_m = {_num(b.x1 - b.x0)}",
                f"h_m = {_num(b.y1 - b.y0)}",
                f"known = {'true' if b.known else 'false'}",
                ""]
    walls = [_centre_line(b) for b in layout.boxes if b.shape == "wall"] + list(layout.segs)
    for w in walls:
        out += [f"[[walls]]   # {w.role}",
                f"x0_m = {_num(w.x0)}",
                f"y0_m = {_num(w.y0)}",
                f"x1_m = {_num(w.x1)}",
                f"y1_m = {_num(w.y1)}",
                f"thickness_m = {_num(w.thickness)}",
                f"known = {'true' if w.known else 'false'}",
                ""]
    for p in layout.posts:
        out += [f"[[posts]]   # {p.role}",
                f"x_m = {_num(p.x)}",
                f"y_m = {_num(p.y)}",
                f"radius_m = {_num(p.r)}",
                f"known = {'true' if p.known else 'false'}",
                ""]
    return "\n".join(out)


def _centre_line(b: _Box) -> _Seg:
    """An axis-aligned wall as a segment along its longer side (ends flush with its edges)."""
    if b.x1 - b.x0 >= b.y1 - b.y0:
        y = (b.y0 + b.y1) / 2
        return _Seg(b.x0, y, b.x1, y, b.y1 - b.y0, b.known, b.role)
    x = (b.x0 + b.x1) / 2
    return _Seg(x, b.y0, x, b.y1, b.x1 - b.x0, b.known, b.role)


# --- difficulty -----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ArenaMeasure:
    """What `measure_scenario` finds: solvability, the difficulty table and the clairvoyant optimum."""

    solvable: bool
    difficulty: dict[str, Any]
    optimal_path: tuple[tuple[float, float], ...]   # waypoints [m]; () when unsolvable


@dataclasses.dataclass(frozen=True)
class _Shapes:
    """Every obstacle of a scenario as arrays [m]: axis-aligned boxes (the boxes and the walls
    along x or y) as (x0, x1, y0, y1); walls at an angle as (centre x, centre y, unit vector
    along x, y, half length, half thickness); posts as (x, y, radius)."""

    boxes: np.ndarray
    walls: np.ndarray
    posts: np.ndarray


def _shapes(scenario: Scenario) -> _Shapes:
    boxes = [(o.x_m - o.w_m / 2, o.x_m + o.w_m / 2, o.y_m - o.h_m / 2, o.y_m + o.h_m / 2) for o in scenario.obstacles]
    walls = []
    for w in scenario.walls:
        cx, cy, ux, uy, a, b = w.frame()
        if w.axis_aligned:
            ex, ey = abs(ux) * a + abs(uy) * b, abs(uy) * a + abs(ux) * b
            boxes.append((cx - ex, cx + ex, cy - ey, cy + ey))
        else:
            walls.append((cx, cy, ux, uy, a, b))
    return _Shapes(np.array(boxes, dtype=np.float64).reshape(-1, 4), np.array(walls, dtype=np.float64).reshape(-1, 6),
                   np.array([(p.x_m, p.y_m, p.radius_m) for p in scenario.posts], dtype=np.float64).reshape(-1, 3))


def _box_edges(scenario: Scenario) -> np.ndarray:
    """(n, 4) array of x0, x1, y0, y1 [m] of every box and every wall along x or y."""
    return _shapes(scenario).boxes


def _wall_local(points_x: np.ndarray, points_y: np.ndarray, walls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (any shape, broadcast against a last axis of walls) in each wall's frame: (along, across)."""
    dx, dy = points_x - walls[:, 0], points_y - walls[:, 1]
    return dx * walls[:, 2] + dy * walls[:, 3], dy * walls[:, 2] - dx * walls[:, 3]


def _sample_polyline(points: Sequence[Sequence[float]], step_m: float) -> np.ndarray:
    """Points along the polyline at most `step_m` apart, both ends included."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, math.ceil(float(np.hypot(*(b - a))) / step_m))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def _clearances(points: np.ndarray, shapes: _Shapes, width_m: float, height_m: float) -> np.ndarray:
    """Exact distance [m] from each point to the nearest box, wall, post or the arena's wall."""
    boxes = shapes.boxes
    x, y = points[:, 0], points[:, 1]
    wall = np.maximum(np.minimum.reduce([x, width_m - x, y, height_m - y]), 0.0)
    dx = np.maximum(np.maximum(boxes[None, :, 0] - x[:, None], x[:, None] - boxes[None, :, 1]), 0.0)
    dy = np.maximum(np.maximum(boxes[None, :, 2] - y[:, None], y[:, None] - boxes[None, :, 3]), 0.0)
    out = np.minimum(wall, np.hypot(dx, dy).min(axis=1, initial=np.inf))
    if len(shapes.walls):
        along, across = _wall_local(x[:, None], y[:, None], shapes.walls)
        d = np.hypot(np.maximum(np.abs(along) - shapes.walls[:, 4], 0.0),
                     np.maximum(np.abs(across) - shapes.walls[:, 5], 0.0))
        out = np.minimum(out, d.min(axis=1))
    if len(shapes.posts):
        p = shapes.posts
        d = np.hypot(x[:, None] - p[:, 0], y[:, None] - p[:, 1]) - p[:, 2]
        out = np.minimum(out, np.maximum(d, 0.0).min(axis=1))
    return out


def _ray_directions() -> np.ndarray:
    angles = np.arange(RAY_COUNT) * (2 * math.pi / RAY_COUNT)
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    dirs[np.abs(dirs) < 1e-12] = 0.0
    return dirs


def _slab(p: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a ray p + t·c is between lo and hi on one axis: (t_near, t_far), broadcast."""
    moving = c != 0
    inv = np.where(moving, 1.0 / np.where(moving, c, 1.0), 0.0)
    t1, t2 = (lo - p) * inv, (hi - p) * inv
    inside = (p >= lo) & (p <= hi)
    near = np.where(moving, np.minimum(t1, t2), np.where(inside, -np.inf, np.inf))
    far = np.where(moving, np.maximum(t1, t2), np.where(inside, np.inf, -np.inf))
    return near, far


def _ray_lengths(points: np.ndarray, shapes: _Shapes, width_m: float, height_m: float) -> np.ndarray:
    """(n, RAY_COUNT): free length [m] from each point along each ray to a box, a wall, a post or
    the arena's wall, at most RAY_LENGTH_M."""
    boxes = shapes.boxes
    dirs = _ray_directions()
    px, py = points[:, 0, None, None], points[:, 1, None, None]
    cx, cy = dirs[None, :, 0, None], dirs[None, :, 1, None]
    near_x, far_x = _slab(px, cx, boxes[None, None, :, 0], boxes[None, None, :, 1])
    near_y, far_y = _slab(py, cy, boxes[None, None, :, 2], boxes[None, None, :, 3])
    enter, leave = np.maximum(near_x, near_y), np.minimum(far_x, far_y)
    hit = np.isfinite(enter) & (leave >= np.maximum(enter, 0.0))
    t_box = np.where(hit, np.maximum(enter, 0.0), np.inf).min(axis=2, initial=np.inf)
    if len(shapes.walls):   # the slab method in each wall's frame
        w = shapes.walls
        lp, lq = _wall_local(px, py, w)
        ldx, ldy = cx * w[:, 2] + cy * w[:, 3], cy * w[:, 2] - cx * w[:, 3]
        ldx = np.where(np.abs(ldx) < 1e-12, 0.0, ldx)
        ldy = np.where(np.abs(ldy) < 1e-12, 0.0, ldy)
        near_a, far_a = _slab(lp, ldx, -w[:, 4], w[:, 4])
        near_b, far_b = _slab(lq, ldy, -w[:, 5], w[:, 5])
        enter, leave = np.maximum(near_a, near_b), np.minimum(far_a, far_b)
        hit = np.isfinite(enter) & (leave >= np.maximum(enter, 0.0))
        t_box = np.minimum(t_box, np.where(hit, np.maximum(enter, 0.0), np.inf).min(axis=2))
    if len(shapes.posts):   # p + t·c meets the circle |p + t·c − centre| = r (c is a unit vector)
        q = shapes.posts
        fx, fy = px - q[:, 0], py - q[:, 1]
        b = fx * cx + fy * cy
        c = fx * fx + fy * fy - q[:, 2] ** 2
        disc = b * b - c
        root = np.sqrt(np.maximum(disc, 0.0))
        t = np.where(c <= 0.0, 0.0, np.where((disc >= 0.0) & (b <= 0.0), -b - root, np.inf))
        t_box = np.minimum(t_box, t.min(axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        wx = np.where(cx > 0, (width_m - px) / cx, np.where(cx < 0, -px / cx, np.inf))[..., 0]
        wy = np.where(cy > 0, (height_m - py) / cy, np.where(cy < 0, -py / cy, np.inf))[..., 0]
    return np.minimum.reduce([t_box, np.maximum(wx, 0.0), np.maximum(wy, 0.0),
                              np.full_like(t_box, RAY_LENGTH_M)])


def _dispersion(points: np.ndarray, shapes: _Shapes, width_m: float, height_m: float) -> float:
    """Mean over the points of the free/occupied switches along their rays (see the module's docstring)."""
    step = RAY_STEP_M
    nx, ny = math.ceil(width_m / step), math.ceil(height_m / step)
    occupied = np.zeros((ny, nx), dtype=np.bool_)
    for x0, x1, y0, y1 in shapes.boxes:   # cells whose centre lies in the box
        c0, c1 = max(math.ceil(x0 / step - 0.5), 0), math.floor(x1 / step - 0.5) + 1
        r0, r1 = max(math.ceil(y0 / step - 0.5), 0), math.floor(y1 / step - 0.5) + 1
        occupied[r0:max(r1, r0), c0:max(c1, c0)] = True
    if len(shapes.walls) or len(shapes.posts):   # cells whose centre lies in a wall at an angle or a post
        centres_x = (np.arange(nx) + 0.5) * step
        centres_y = (np.arange(ny) + 0.5) * step
        for w in shapes.walls:
            along, across = _wall_local(centres_x[None, :, None], centres_y[:, None, None], w[None, :])
            occupied |= (np.abs(along[..., 0]) <= w[4]) & (np.abs(across[..., 0]) <= w[5])
        for x, y, r in shapes.posts:
            occupied |= np.hypot(centres_x[None, :] - x, centres_y[:, None] - y) <= r
    along = np.arange(0.0, RAY_LENGTH_M + step / 2, step)
    dirs = _ray_directions()
    xs = points[:, 0, None, None] + along[None, None, :] * dirs[None, :, 0, None]
    ys = points[:, 1, None, None] + along[None, None, :] * dirs[None, :, 1, None]
    on_arena = (xs >= 0) & (xs <= width_m) & (ys >= 0) & (ys <= height_m)
    ix = np.clip((xs / step).astype(np.int64), 0, nx - 1)
    iy = np.clip((ys / step).astype(np.int64), 0, ny - 1)
    values = occupied[iy, ix]
    switches = (values[..., 1:] != values[..., :-1]) & on_arena[..., 1:] & on_arena[..., :-1]
    return float(switches.sum(axis=(1, 2)).mean())


def _score(difficulty: dict[str, Any], solvable: bool, inflation_m: float) -> float:
    def clip(v: float) -> float:
        return min(max(v, 0.0), 1.0)

    terms = {
        "narrow": clip((CD_OPEN_M - difficulty["characteristic_dimension_m"]) / (CD_OPEN_M - 2 * inflation_m)),
        "pinch": clip((PINCH_OPEN_M - difficulty["narrowest_dimension_m"]) / (PINCH_OPEN_M - 2 * inflation_m)),
        "tight": clip((CLEARANCE_OPEN_M - difficulty["mean_clearance_m"]) / (CLEARANCE_OPEN_M - inflation_m)),
        "clutter": clip(difficulty["dispersion"] / DISPERSION_DENSE),
        "detour": clip((difficulty["detour_ratio"] - 1.0) / DETOUR_LONG) if solvable else 1.0,
        "surprise": 1.0 if difficulty["known_path_blocked"] else 0.0,
    }
    return sum(SCORE_WEIGHTS[k] * v for k, v in terms.items())


def band_of(score: float) -> str:
    """"easy" below BAND_MEDIUM, "hard" from BAND_HARD, "medium" between."""
    return "easy" if score < BAND_MEDIUM else "hard" if score >= BAND_HARD else "medium"


def measure_scenario(scenario: Scenario, config: PlannerConfig | None = None) -> ArenaMeasure:
    """Solvability (A* with every obstacle known) and the difficulty metrics of any scenario.

    Raises the planner's StartBlocked, GoalBlocked or OutsideArena (NoPathError) when the start
    or the target is not free with every obstacle known; an Unreachable target makes the
    scenario unsolvable and the metrics follow the straight segment from start to target.
    """
    cfg = config or PlannerConfig()
    start, target = scenario.start.xy, scenario.target.xy
    grid = OccupancyGrid.from_scenario(scenario, cfg, all_obstacles=True)
    try:
        optimum: PlanResult | None = plan(grid, start, target)
    except Unreachable:
        optimum = None
    try:
        known = plan(OccupancyGrid.from_scenario(scenario, cfg), start, target)
        known_blocked = grid.path_blocked(known.waypoints)
    except NoPathError:
        known_blocked = False
    path = optimum.waypoints if optimum is not None else (start, target)
    points = _sample_polyline(path, cfg.resolution_m)
    shapes = _shapes(scenario)
    W, H = scenario.arena.width_m, scenario.arena.height_m
    clearance = _clearances(points, shapes, W, H)
    rays = _ray_lengths(points, shapes, W, H)
    half = RAY_COUNT // 2
    widths = (rays[:, :half] + rays[:, half:]).min(axis=1)   # the narrowest line through each point
    difficulty: dict[str, Any] = {
        "closest_obstacle_m": float(clearance.min()),
        "mean_clearance_m": float(clearance.mean()),
        "dispersion": _dispersion(points, shapes, W, H),
        "characteristic_dimension_m": float(widths.mean()),
        "narrowest_dimension_m": float(widths.min()),
    }
    if optimum is not None:
        straight = math.dist(start, target)
        difficulty["optimal_length_m"] = optimum.length_m
        difficulty["detour_ratio"] = optimum.length_m / straight if straight >= 1e-3 else 1.0
    difficulty["known_path_blocked"] = bool(known_blocked)
    score = round(_score(difficulty, optimum is not None, cfg.inflation_m), 4)
    difficulty["score"] = score
    difficulty["band"] = band_of(score)
    return ArenaMeasure(solvable=optimum is not None, difficulty=difficulty,
                        optimal_path=tuple(path) if optimum is not None else ())


# --- generating -----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class GeneratedArena:
    """One generated arena: its scenario (with .generated set), the file's text and its labels."""

    scenario: Scenario
    toml_text: str
    family: str
    solvable: bool
    difficulty: dict[str, Any]
    optimal_path: tuple[tuple[float, float], ...]   # the clairvoyant optimum's waypoints [m]; () if unsolvable
    index: int
    seed: int
    passage_width_m: float | None = None

    @property
    def name(self) -> str:
        return self.scenario.name

    @property
    def file_name(self) -> str:
        return f"{self.scenario.name}.toml"


def _families(families: Sequence[str] | None) -> tuple[str, ...]:
    """The families asked for, in ALL_FAMILY_NAMES order (the default cycle, FAMILY_NAMES, when
    none is); ArenaError naming an unknown one."""
    if families is None:
        return FAMILY_NAMES
    if isinstance(families, str):
        families = families.split(",")
    asked = [f.strip() for f in families if f.strip()]
    for name in asked:
        if name not in _BY_NAME:
            raise ArenaError(f"unknown family {name!r} (families: {', '.join(ALL_FAMILY_NAMES)})")
    if not asked:
        raise ArenaError(f"no family given (families: {', '.join(ALL_FAMILY_NAMES)})")
    return tuple(f for f in ALL_FAMILY_NAMES if f in asked)


def _check_count_and_seed(count: int, seed: int) -> None:
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_COUNT:
        raise ArenaError(f"count must be a whole number from 1 to {MAX_COUNT}, got {count!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ArenaError(f"seed must be a whole number ≥ 0, got {seed!r}")


def generate_arena(seed: int, index: int, family: str, config: PlannerConfig | None = None,
                   name_digits: int = 4) -> GeneratedArena:
    """Arena `index` of `seed`, of the given family: the same arguments give the same text.

    Draws from PCG64(SeedSequence([seed, index])) until the draw meets the family's constraints
    (see the module's docstring); GenerationFailed after MAX_TRIES draws.
    """
    if isinstance(index, bool) or not isinstance(index, int) or index < 1:
        raise ArenaError(f"index must be a whole number ≥ 1, got {index!r}")
    _check_count_and_seed(1, seed)
    fam = _BY_NAME[_families([family])[0]]
    cfg = config or PlannerConfig()
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    name = f"arena-{index:0{name_digits}d}-{family}"
    source = f"<{name}>"
    why = ""
    for _ in range(MAX_TRIES):
        try:
            d = _Draw(rng, cfg)
            layout = _mirror(fam.draw(d), d.chance(0.5), d.chance(0.5))
        except _Redraw as exc:
            why = str(exc)
            continue
        draft = parse_scenario(_toml_text(name, layout, family, seed, index, None), source=source)
        W, H = draft.arena.width_m, draft.arena.height_m
        if any(o.x_m - o.w_m / 2 < -1e-9 or o.x_m + o.w_m / 2 > W + 1e-9 or o.y_m - o.h_m / 2 < -1e-9
               or o.y_m + o.h_m / 2 > H + 1e-9 for o in draft.obstacles):
            why = "a box off the arena"
            continue
        if any(not (-1e-9 <= x <= W + 1e-9 and -1e-9 <= y <= H + 1e-9) for w in draft.walls for x, y in w.corners()):
            why = "a wall off the arena"
            continue
        if any(p.x_m - p.radius_m < -1e-9 or p.x_m + p.radius_m > W + 1e-9 or p.y_m - p.radius_m < -1e-9
               or p.y_m + p.radius_m > H + 1e-9 for p in draft.posts):
            why = "a post off the arena"
            continue
        try:
            measure = measure_scenario(draft, cfg)
        except NoPathError as exc:   # start or target not free
            why = str(exc)
            continue
        if fam.expects != "either" and measure.solvable != (fam.expects == "solvable"):
            why = "solvable" if measure.solvable else "unsolvable"
            continue
        generated: dict[str, Any] = {"family": family, "seed": seed, "index": index, "solvable": measure.solvable}
        if layout.passage_width_m is not None:
            generated["passage_width_m"] = layout.passage_width_m
        generated["difficulty"] = measure.difficulty
        text = _toml_text(name, layout, family, seed, index, generated)
        scenario = parse_scenario(text, source=source)
        return GeneratedArena(scenario=scenario, toml_text=text, family=family, solvable=measure.solvable,
                              difficulty=scenario.generated["difficulty"], optimal_path=measure.optimal_path,
                              index=index, seed=seed, passage_width_m=layout.passage_width_m)
    raise GenerationFailed(f"arena {index} ({family}, seed {seed}): no draw met the family's constraints "
                           f"in {MAX_TRIES} tries (the last: {why})")


def generate_arenas(count: int, seed: int, families: Sequence[str] | None = None,
                    config: PlannerConfig | None = None,
                    progress: Callable[[int, int], None] | None = None) -> list[GeneratedArena]:
    """`count` arenas, arena i (from 1) of family (i − 1) mod F among the families asked for
    (all of them by default, in FAMILY_NAMES order). `progress(done, count)` is called after each.

    Raises ArenaError for a count outside 1..MAX_COUNT, a negative seed or an unknown family,
    GenerationFailed if an arena cannot be drawn.
    """
    _check_count_and_seed(count, seed)
    names = _families(families)
    digits = max(4, len(str(count)))
    arenas = []
    for i in range(1, count + 1):
        arenas.append(generate_arena(seed, i, names[(i - 1) % len(names)], config, digits))
        if progress is not None:
            progress(i, count)
    return arenas


# --- writing --------------------------------------------------------------------------------------

def index_row(arena: GeneratedArena) -> dict[str, Any]:
    """The arena's row in index.json and index.csv (INDEX_FIELDS; None where it does not apply)."""
    s, d = arena.scenario, arena.difficulty
    row: dict[str, Any] = dict.fromkeys(INDEX_FIELDS)
    row.update(file=arena.file_name, name=arena.name, index=arena.index, seed=arena.seed, family=arena.family,
               solvable=arena.solvable, passage_width_m=arena.passage_width_m, width_m=s.arena.width_m,
               height_m=s.arena.height_m, mission=s.mission.kind, known_obstacles=len(s.known_shapes),
               unknown_obstacles=len(s.unknown_shapes))
    row.update({k: v for k, v in d.items() if k in row})
    return row


def write_arenas(arenas: Sequence[GeneratedArena], out_dir: Path | str) -> list[Path]:
    """Write each arena's file, index.json and index.csv into `out_dir` (made if missing), each
    atomically; remove arena files (arena-NNNN-family.toml) of an earlier run that this one did not
    write. Returns the arena files' paths. ArenaError if `out_dir` is an existing file."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ArenaError(f"{out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for arena in arenas:
        path = out / arena.file_name
        write_atomic(path, arena.toml_text)
        paths.append(path)
    written = {p.name for p in paths}
    for old in sorted(out.glob("arena-*.toml")):
        if _ARENA_FILE.match(old.name) and old.name not in written:
            old.unlink()
    rows = [index_row(a) for a in arenas]
    write_atomic(out / "index.json", json.dumps(rows, indent=1, allow_nan=False) + "\n")
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=INDEX_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in rows)
    write_atomic(out / "index.csv", buffer.getvalue())
    return paths


def write_gallery(arenas: Sequence[GeneratedArena], path: Path | str, columns: int = 4) -> Path:
    """A contact sheet (PNG) of the first GALLERY_COUNT arenas: the border, known obstacles (boxes,
    walls, posts) grey, unknown ones hatched red, the start (a green disk of the robot radius, a tick for its heading),
    the target (a star), the clairvoyant optimum (blue), and a caption: index, family, solvable,
    band and score. Written atomically; returns the path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch, Polygon, Rectangle

    shown = list(arenas[:GALLERY_COUNT])
    if not shown:
        raise ArenaError("no arenas to draw")
    radius_m = PlannerConfig().robot_radius_m
    rows = math.ceil(len(shown) / columns)
    fig = Figure(figsize=(4.4 * columns, 3.7 * rows + 0.6), dpi=100)
    FigureCanvasAgg(fig)
    for k, arena in enumerate(shown):
        s = arena.scenario
        W, H = s.arena.width_m, s.arena.height_m
        ax = fig.add_subplot(rows, columns, k + 1)
        ax.add_patch(Rectangle((0, 0), W, H, fill=False, lw=2.0, ec="black"))
        for o in s.shapes:
            style = dict(fc="0.55", ec="0.25", lw=0.8) if o.known else \
                dict(fc="#fde0dd", ec="#d62728", lw=1.3, hatch="////")
            if o.kind == "box":
                ax.add_patch(Rectangle((o.x_m - o.w_m / 2, o.y_m - o.h_m / 2), o.w_m, o.h_m, **style))
            elif o.kind == "wall":
                ax.add_patch(Polygon(o.corners(), closed=True, **style))
            else:
                ax.add_patch(Circle((o.x_m, o.y_m), o.radius_m, **style))
        if arena.optimal_path:
            xs, ys = zip(*arena.optimal_path)
            ax.plot(xs, ys, color="#1f5fbf", lw=1.3)
        sx, sy = s.start.xy
        h = math.radians(s.start.heading_deg)
        ax.add_patch(Circle((sx, sy), radius_m, fc="#2ca02c", ec="#145214", lw=1.0, alpha=0.8))
        ax.plot([sx, sx + radius_m * math.sin(h)], [sy, sy + radius_m * math.cos(h)], color="#145214", lw=1.5)
        ax.plot(*s.target.xy, marker="*", ms=17, mfc="#ffc400", mec="black", mew=0.8)
        ax.set_xlim(-0.04, W + 0.04)
        ax.set_ylim(-0.04, H + 0.04)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        for spine in ax.spines.values():
            spine.set_visible(False)
        trip = ", out and back" if s.mission.kind == "out-and-back" else ""
        ax.set_title(f"{arena.index}. {arena.family}{trip}\n{'solvable' if arena.solvable else 'UNSOLVABLE'}, "
                     f"{arena.difficulty['band']} ({arena.difficulty['score']:.2f}), {W:.2f} × {H:.2f} m",
                     fontsize=11)
    handles = [Patch(fc="0.55", ec="0.25", label="known obstacle"),
               Patch(fc="#fde0dd", ec="#d62728", hatch="////", label="unknown obstacle (sonar)"),
               Line2D([], [], color="#1f5fbf", lw=1.3, label="optimum, every obstacle known"),
               Line2D([], [], marker="o", ls="", ms=11, mfc="#2ca02c", mec="#145214",
                      label="start (robot radius, heading)"),
               Line2D([], [], marker="*", ls="", ms=15, mfc="#ffc400", mec="black", label="target")]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=11, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", metadata={"Software": None})
    path = Path(path)
    write_atomic(path, buffer.getvalue())
    return path


# --- the command ----------------------------------------------------------------------------------

def _help_epilog() -> str:
    width = max(len(n) for n in ALL_FAMILY_NAMES)
    families = "\n".join(f"  {name:<{width}}  {text}" for name, text in FAMILIES)
    return f"""families (arena i is of family (i - 1) mod F of those asked for; by default all but those
drawn by name only):
{families}

every file is a scenario (see scenarios/) with a [generated] table: family, seed, index,
solvable (A* finds a path with every obstacle known), passage_width_m (narrow_passage), and
[generated.difficulty], measured along that clairvoyant optimum sampled every 3 cm (the
straight start-target segment when unsolvable), in the spirit of BARN:
  closest_obstacle_m          smallest distance from the path to an obstacle or the wall
  mean_clearance_m            mean of that distance along the path
  dispersion                  free/occupied switches along 16 rays of {RAY_LENGTH_M:g} m from each path
                              point, summed over the rays, mean over the points (walls end rays)
  characteristic_dimension_m  narrowest of the 8 lines through a path point (to the first
                              obstacle or wall each way, {RAY_LENGTH_M:g} m at most), mean over the points
  narrowest_dimension_m       the same, smallest over the points: the tightest place passed
  optimal_length_m, detour_ratio   the optimum's length, and over the straight distance
  known_path_blocked          the path planned on the known obstacles crosses an unknown one
  score in [0, 1] = {' + '.join(f'{w:.2f} {k}' for k, w in SCORE_WEIGHTS.items())}
  band: easy below {BAND_MEDIUM}, medium, hard from {BAND_HARD}
(rovernav.evaluation.arenas explains each term.)

writes DIR/arena-0001-<family>.toml ..., DIR/index.json and DIR/index.csv (one row per arena),
and a contact sheet of the first {GALLERY_COUNT} arenas (DIR/gallery.png, or --picture FILE); arena
files of an earlier run in DIR that this run did not write are removed. The same --seed gives
the same files byte for byte."""


def add_arenas_parser(sub) -> None:
    """Register `rovernav arenas` on the command's subparsers."""
    p = sub.add_parser(
        "arenas", help="generate arenas (scenario files) from families of rooms and tests, with labels",
        description="Write COUNT scenario files drawn from families of arenas that real rooms and the seed's "
                    "tests contain, each labelled with its family, a difficulty and whether it can be solved "
                    "with every obstacle known; the families are cycled, so any count of at least the number "
                    "of families covers them all.",
        epilog=_help_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--count", default="200", metavar="N", help=f"how many arenas, 1 to {MAX_COUNT} (default 200)")
    p.add_argument("--seed", default="1", metavar="S", help="random seed, a whole number ≥ 0 (default 1)")
    p.add_argument("--out", default="out/arenas", metavar="DIR", help="output folder (default out/arenas)")
    p.add_argument("--family", default=None, metavar="F[,F...]",
                   help="only these families (comma-separated; default all)")
    p.add_argument("--picture", default=None, metavar="FILE", type=output_file(".png", ".jpg"),
                   help=f"where to write the contact sheet of the first {GALLERY_COUNT} arenas "
                        "(default DIR/gallery.png)")
    p.set_defaults(func=cmd_arenas)


def _whole(text: str, flag: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ArenaError(f"{flag} must be a whole number, got {text!r}") from None


def cmd_arenas(args: argparse.Namespace) -> int:
    """The `arenas` command: 0 when written, 2 for a bad request or an unwritable folder, 1 if a
    draw fails."""
    started = time.perf_counter()
    try:
        count, seed = _whole(args.count, "--count"), _whole(args.seed, "--seed")
        if not 1 <= count <= MAX_COUNT:
            raise ArenaError(f"--count must be from 1 to {MAX_COUNT}, got {count}")
        if seed < 0:
            raise ArenaError(f"--seed must be ≥ 0, got {seed}")
        families = _families(args.family.split(",") if args.family is not None else None)
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise ArenaError(f"--out {out}: exists and is not a folder")
        picture = Path(args.picture) if args.picture else out / "gallery.png"
        if picture.is_dir():
            raise ArenaError(f"--picture {picture}: is a folder")

        every = 20

        def progress(done: int, total: int) -> None:
            if done % every == 0 or done == total:
                print(f"  {done}/{total} arenas, {time.perf_counter() - started:.1f} s", flush=True)

        print(f"rovernav arenas: {count} arenas, seed {seed}, families: {', '.join(families)}", flush=True)
        arenas = generate_arenas(count, seed, families, progress=progress)
        write_arenas(arenas, out)
        write_gallery(arenas, picture)
    except (ArenaError, OSError) as exc:
        print(f"rovernav arenas: {exc}", file=sys.stderr)
        return 2
    except GenerationFailed as exc:
        print(f"rovernav arenas: {exc}", file=sys.stderr)
        return 1
    print(_summary(arenas))
    print(f"wrote {len(arenas)} arenas, index.json and index.csv to {out}, the contact sheet to {picture}, "
          f"in {time.perf_counter() - started:.1f} s")
    return 0


def _summary(arenas: Sequence[GeneratedArena]) -> str:
    """A table: per family, how many arenas, how many solvable, and how many in each band."""
    width = max(len(n) for n in ALL_FAMILY_NAMES)
    lines = [f"{'family':<{width}}  arenas  solvable  easy  medium  hard"]
    groups: dict[str, list[GeneratedArena]] = {}
    for a in arenas:
        groups.setdefault(a.family, []).append(a)

    def line(label: str, group: Sequence[GeneratedArena]) -> str:
        bands = [a.difficulty["band"] for a in group]
        return (f"{label:<{width}}  {len(group):>6}  {sum(a.solvable for a in group):>8}  "
                f"{bands.count('easy'):>4}  {bands.count('medium'):>6}  {bands.count('hard'):>4}")

    lines += [line(name, groups[name]) for name in ALL_FAMILY_NAMES if name in groups]
    lines.append(line("all", arenas))
    return "\n".join(lines)
