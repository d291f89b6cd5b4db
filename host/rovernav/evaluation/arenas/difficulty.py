"""The difficulty of an arena, measured along its clairvoyant optimum in the spirit of BARN
(the package's docstring defines each metric and the score)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...planning import NoPathError, OccupancyGrid, PlannerConfig, PlanResult, Unreachable, plan
from ...scenario import Scenario

RAY_COUNT = 16
RAY_LENGTH_M = 1.0
RAY_STEP_M = 0.01
CD_OPEN_M = 1.6  # a characteristic dimension this wide is open floor
PINCH_OPEN_M = 1.0  # a narrowest place this wide is no squeeze
CLEARANCE_OPEN_M = 0.45  # a mean clearance this large is open floor
DISPERSION_DENSE = 15.0  # this many switches is dense clutter
DETOUR_LONG = 0.5  # a path 50 % longer than the straight line is a long detour
SCORE_WEIGHTS = {"narrow": 0.15, "pinch": 0.15, "tight": 0.10, "clutter": 0.15, "detour": 0.25, "surprise": 0.20}
# Over the 600 arenas of seeds 1-3 the score's tertiles fell at 0.46 and 0.64.
BAND_MEDIUM = 0.45
BAND_HARD = 0.65

# --- difficulty -----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ArenaMeasure:
    """What `measure_scenario` finds: solvability, the difficulty table and the clairvoyant optimum."""

    solvable: bool
    difficulty: dict[str, Any]
    optimal_path: tuple[tuple[float, float], ...]  # waypoints [m]; () when unsolvable


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
    return _Shapes(
        np.array(boxes, dtype=np.float64).reshape(-1, 4),
        np.array(walls, dtype=np.float64).reshape(-1, 6),
        np.array([(p.x_m, p.y_m, p.radius_m) for p in scenario.posts], dtype=np.float64).reshape(-1, 3),
    )


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
        d = np.hypot(
            np.maximum(np.abs(along) - shapes.walls[:, 4], 0.0), np.maximum(np.abs(across) - shapes.walls[:, 5], 0.0)
        )
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
    if len(shapes.walls):  # the slab method in each wall's frame
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
    if len(shapes.posts):  # p + t·c meets the circle |p + t·c − centre| = r (c is a unit vector)
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
    return np.minimum.reduce([t_box, np.maximum(wx, 0.0), np.maximum(wy, 0.0), np.full_like(t_box, RAY_LENGTH_M)])


def _dispersion(points: np.ndarray, shapes: _Shapes, width_m: float, height_m: float) -> float:
    """Mean over the points of the free/occupied switches along their rays (see the module's docstring)."""
    step = RAY_STEP_M
    nx, ny = math.ceil(width_m / step), math.ceil(height_m / step)
    occupied = np.zeros((ny, nx), dtype=np.bool_)
    for x0, x1, y0, y1 in shapes.boxes:  # cells whose centre lies in the box
        c0, c1 = max(math.ceil(x0 / step - 0.5), 0), math.floor(x1 / step - 0.5) + 1
        r0, r1 = max(math.ceil(y0 / step - 0.5), 0), math.floor(y1 / step - 0.5) + 1
        occupied[r0 : max(r1, r0), c0 : max(c1, c0)] = True
    if len(shapes.walls) or len(shapes.posts):  # cells whose centre lies in a wall at an angle or a post
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
    """ "easy" below BAND_MEDIUM, "hard" from BAND_HARD, "medium" between."""
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
    widths = (rays[:, :half] + rays[:, half:]).min(axis=1)  # the narrowest line through each point
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
    return ArenaMeasure(
        solvable=optimum is not None, difficulty=difficulty, optimal_path=tuple(path) if optimum is not None else ()
    )
