"""The families of arenas, each drawn with the start on the left and the target on the right,
and the table of them (FAMILIES)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from ...planning import NoPathError, OccupancyGrid, plan
from .cellular import _cellular
from .draw import (
    NARROW_EXTRA_M,
    POST_DIAMETERS_M,
    SEED_BOX_SIZES_M,
    START_AT_TARGET_RANGE_M,
    WALL_THICKNESS_RANGE_M,
    _Box,
    _Draw,
    _Layout,
    _Post,
    _Redraw,
    _Seg,
    _wall,
)

# --- the families, each drawn with the start on the left and the target on the right --------------


def _scattered(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.25 * W), d.point(0.75 * W, W)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(3, 7), (start, target), unknown_p=0.4, role="box", x_range=(0.2 * W, 0.85 * W))
    if len({b.known for b in boxes}) < 2:
        raise _Redraw("want known and unknown boxes")
    return _Layout(
        W, H, start, d.heading(start, target), target, boxes, f"{len(boxes)} boxes of the seed's sizes, some unknown"
    )


def _divider(
    x0: float, x1: float, gap_lo: float, gap_hi: float, H: float, known: Sequence[bool], role: str, shape: str = "wall"
) -> list[_Box]:
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
        segs.append(
            _Seg(
                round(hinge[0], 6),
                round(hinge[1], 6),
                round(tip[0], 6),
                round(tip[1], 6),
                t,
                leaf_known,
                "door leaf, open",
            )
        )
        # What the leaf covers, so that no box is scattered onto it.
        keep_out = [_Box(hinge[0] - t, tip[0] + t, min(hinge[1], tip[1]) - t, max(hinge[1], tip[1]) + t, True, "")]
        note = (
            f"a divider wall with a door open at {round(math.degrees(angle))}°"
            + ("" if wall_known else " (the wall unknown)")
            + ("" if leaf_known else ", the door leaf unknown")
        )
    start = d.point(0, x0 - 0.3)
    target = d.point(x0 + t + (gap if door else 0.0) + 0.3, W)
    if d.chance(0.5):
        placed = boxes + keep_out
        d.scatter(placed, 1, (start, target), unknown_p=0.5, role="box", near_line_p=0.0)
        boxes += placed[len(boxes) + len(keep_out) :]
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
    boxes = [
        _wall(x0, x0 + length, y_lo - t, y_lo, d.chance(0.6), "corridor wall, lower"),
        _wall(x0, x0 + length, y_hi, y_hi + t, d.chance(0.6), "corridor wall, upper"),
    ]
    closed = d.chance(0.5)
    if closed:  # bulkheads from the corridor's mouth to the arena's wall: the corridor is the only way
        known = d.chance(0.7)
        boxes += [
            _wall(x0, x0 + t, 0.0, y_lo - t, known, "bulkhead, lower"),
            _wall(x0, x0 + t, y_hi + t, H, known, "bulkhead, upper"),
        ]
    if inner - 0.08 >= 2 * inf + 0.06 and d.chance(0.4):
        bx = d.u(x0 + 0.2, x0 + length - 0.2)
        y0, y1 = (y_lo, y_lo + 0.08) if d.chance(0.5) else (y_hi - 0.08, y_hi)
        boxes.append(_wall(bx - 0.04, bx + 0.04, y0, y1, False, "box against a corridor wall", "box"))
    # Open, the ends face the mouths (the corridor is on the way); closed, they may be anywhere.
    reach = 0.4 if closed else 0.12
    start = d.point(0, x0 - 0.2, yc - reach, yc + reach)
    target = d.point(x0 + length + 0.2, W, yc - reach, yc + reach)
    unknown = all(not b.known for b in boxes[:2])
    note = ("a closed corridor (the only way through)" if closed else "an open corridor") + (
        ", its walls unknown" if unknown else ", some walls unknown" if not all(b.known for b in boxes) else ""
    )
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
    which = d.pick(("all", "back", "none"))  # what is unknown
    boxes = [
        _wall(xc, xc + t, yc - t, yc + back, which == "none", "L trap, back"),
        _wall(xc - floor, xc, yc - t, yc, which != "all", "L trap, floor"),
    ]
    # The dead end faces the start: the straight line runs into the inside corner.
    start = d.point(0, xc - floor - 0.1, yc + 0.1, yc + 0.6 * back)
    target = d.point(xc + t + 0.25, W, yc + 0.1, yc + 0.8 * back)
    note = (
        "an L-shaped dead end facing the start" + {"all": ", unknown", "back": ", its back unknown", "none": ""}[which]
    )
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note)


def _trap_u(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = _trap_thickness(d)
    room = 2 * inf + 0.1  # a way round on either side
    inner = d.u(2 * inf + 0.06, min(2 * inf + 0.40, H - 2 * t - 2 * room))
    depth = d.u(0.35, 0.7)
    half = inner / 2 + t
    slack = (H - 2 * half - 2 * room) / 2
    yc = d.u(H / 2 - slack, H / 2 + slack)
    xb = d.u(max(0.5 * W, depth + 0.7), min(0.7 * W, W - t - 0.5))
    which = d.pick(("all", "back", "none"))
    y_lo, y_hi = round(yc - inner / 2, 6), round(yc + inner / 2, 6)
    boxes = [
        _wall(xb, xb + t, y_lo - t, y_hi + t, which == "none", "U trap, back"),
        _wall(xb - depth, xb, y_hi, y_hi + t, which != "all", "U trap, upper arm"),
        _wall(xb - depth, xb, y_lo - t, y_lo, which != "all", "U trap, lower arm"),
    ]
    start = d.point(0, xb - depth - 0.15, yc - 0.1, yc + 0.1)
    target = d.point(xb + t + 0.2, W, yc - 0.15, yc + 0.15)
    note = (
        "a U-shaped dead end facing the start" + {"all": ", unknown", "back": ", its back unknown", "none": ""}[which]
    )
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
    post_p = d.pick((0.0, 0.3, 0.6))  # how many of them are round posts (table legs, pillars)
    for _ in range(8 * wanted):
        if len(items) == wanted:
            break
        w, h = d.pick(sizes), d.pick(sizes)
        post = d.chance(post_p)
        if post:
            w = h = d.pick(POST_DIAMETERS_M)
        if d.chance(0.7):  # in a band 0.9 m wide along the way
            along, off = d.rng.uniform(0.1, 0.9), d.rng.uniform(-0.45, 0.45)
            cx = round(ax + along * (bx - ax) + off * across[0], 3)
            cy = round(ay + along * (by - ay) + off * across[1], 3)
        else:
            cx, cy = d.u(0.15 * W + w / 2, 0.85 * W - w / 2), d.u(h / 2, H - h / 2)
        item = (
            _Post(cx, cy, w / 2, d.chance(0.4), "clutter, post")
            if post
            else d.box(cx, cy, w, h, d.chance(0.4), "clutter")
        )
        if not d.fits(item, items, (start, target), gap_m=0.01):
            continue
        trial = grid.copy()
        if post:
            trial.add_post(cx, cy, w / 2)
        else:
            trial.add_box(cx, cy, w, h)
        try:  # keep it only if a way through remains
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
    return _Layout(
        W, H, start, d.heading(start, target), target, boxes, f"dense clutter: {what}, most unknown", posts=posts
    )


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
    note = (
        f"a {width * 100:.1f} cm passage {kind} "
        f"({'known' if knowledge == 'known' else 'unknown' if knowledge == 'unknown' else 'half known'}); "
        f"the rover's limit is {2 * inf * 100:.0f} cm"
    )
    return _Layout(W, H, start, d.heading(start, target), target, boxes, note, passage_width_m=width)


def _unknown_on_path(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start, target = d.point(0, 0.25 * W), d.point(0.75 * W, W)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(2, 4), (start, target), unknown_p=0.0, role="box", near_line_p=0.4)
    path = d.known_path(boxes, start, target)
    if path.length_m < 0.9:
        raise _Redraw("too short a path")
    fractions = [d.rng.uniform(0.35, 0.65)] if d.chance(0.6) else [d.rng.uniform(0.25, 0.42), d.rng.uniform(0.58, 0.75)]
    big = SEED_BOX_SIZES_M[1:]
    for f in fractions:
        box = d.across_path(path.waypoints, f, *d.pick(big), role="unknown, across the known map's optimal path")
        if not d.fits(box, boxes, (start, target)):
            raise _Redraw("the box on the path does not fit")
        boxes.append(box)
    return _Layout(
        W,
        H,
        start,
        d.heading(start, target),
        target,
        boxes,
        f"{len(fractions)} unknown box{'es' if len(fractions) > 1 else ''} across the optimal path of the known map",
    )


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
    return _Layout(
        W,
        H,
        start,
        d.heading(start, target),
        target,
        boxes,
        f"{n_near} unknown box{'es' if n_near > 1 else ''} beside the {which}",
    )


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
    return _Layout(
        W,
        H,
        start,
        d.heading(start, target),
        target,
        boxes,
        f"{sum(not b.known for b in boxes)} unknown boxes against the arena's walls, one beside the way",
    )


def _out_and_back(d: _Draw) -> _Layout:
    W, H = d.width_m, d.height_m
    start = d.point(0, 0.25 * W, 0, 0.3 * H)
    target = d.point(0.75 * W, W, 0.7 * H, H)
    boxes: list[_Box] = []
    d.scatter(boxes, d.whole(1, 3), (start, target), unknown_p=0.0, role="box")
    n_known = len(boxes)
    if d.chance(0.6):
        path = d.known_path(boxes, start, target)
        box = d.across_path(
            path.waypoints,
            d.rng.uniform(0.3, 0.7),
            *d.pick(SEED_BOX_SIZES_M[1:]),
            role="unknown, across the known map's optimal path",
        )
        if d.fits(box, boxes, (start, target)):
            boxes.append(box)
    d.scatter(boxes, d.whole(1, 2), (start, target), unknown_p=1.0, role="unknown box")
    if len(boxes) == n_known:
        raise _Redraw("no unknown box")
    return _Layout(
        W,
        H,
        start,
        d.heading(start, target),
        target,
        boxes,
        f"out to the target and back, {n_known} known and {len(boxes) - n_known} unknown boxes",
        kind="out-and-back",
        trips=1,
    )


def _unreachable(d: _Draw) -> _Layout:
    W, H, inf = d.width_m, d.height_m, d.inflation_m
    t = d.thickness()
    start = d.point(0, 0.3 * W)
    variant = d.pick(("ring", "ring", "corner", "divider"))
    if variant == "ring":
        ax, ay = d.u(inf + 0.04, inf + 0.14), d.u(inf + 0.04, inf + 0.14)  # inside half sizes
        cx = d.u(0.6 * W, W - ax - t - 0.05)
        cy = d.u(ay + t + 0.05, H - ay - t - 0.05)
        target = (d.u(cx - (ax - d.clear_m), cx + (ax - d.clear_m)), d.u(cy - (ay - d.clear_m), cy + (ay - d.clear_m)))
        sides = [d.chance(0.5) for _ in range(4)]
        boxes = [
            _wall(cx - ax - t, cx - ax, cy - ay - t, cy + ay + t, sides[0], "enclosure, left"),
            _wall(cx + ax, cx + ax + t, cy - ay - t, cy + ay + t, sides[1], "enclosure, right"),
            _wall(cx - ax, cx + ax, cy - ay - t, cy - ay, sides[2], "enclosure, bottom"),
            _wall(cx - ax, cx + ax, cy + ay, cy + ay + t, sides[3], "enclosure, top"),
        ]
        note = "the target inside a closed box of walls"
    elif variant == "corner":
        c = d.clear_m
        lx, ly = d.u(2 * c + 0.01, 2 * c + 0.25), d.u(2 * c + 0.01, 2 * c + 0.25)  # inside sizes
        known = d.chance(0.5)
        boxes = [
            _wall(W - lx - t, W - lx, H - ly - t, H, known, "corner enclosure, side"),
            _wall(W - lx, W, H - ly - t, H - ly, d.chance(0.5), "corner enclosure, front"),
        ]
        target = (d.u(W - lx + c, W - c), d.u(H - ly + c, H - c))
        note = "the target walled into a corner"
    else:
        x0 = d.u(0.45 * W, 0.65 * W)
        boxes = [_wall(x0, x0 + t, 0.0, H, d.chance(0.5), "divider without a gap")]
        target = d.point(x0 + t + 0.25, W)
        note = "a divider wall with no gap between start and target"
    unknown = sum(not b.known for b in boxes)
    note += f" ({unknown} of {len(boxes)} walls unknown)" if unknown else ""
    d.scatter(boxes, d.whole(0, 2), (start, target), unknown_p=0.5, role="box", near_line_p=0.0, x_range=(0.0, 0.5 * W))
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
        boxes.append(
            d.beside(
                start,
                d.rng.uniform(-180, 180),
                d.rng.uniform(d.clear_m + 0.05, d.clear_m + 0.3),
                *d.pick(SEED_BOX_SIZES_M),
                role="box near the start",
                known=d.chance(0.5),
            )
        )
        if not d.fits(boxes[0], [], (start, target)):
            raise _Redraw("the box near the start does not fit")
    d.scatter(boxes, d.whole(1, 3), (start, target), unknown_p=0.5, role="box", near_line_p=0.0)
    return _Layout(
        W,
        H,
        start,
        float(d.whole(0, 7) * 45),
        target,
        boxes,
        f"the target {math.dist(start, target) * 100:.1f} cm from the start",
    )


@dataclasses.dataclass(frozen=True)
class _Family:
    name: str
    description: str
    draw: Callable[[_Draw], _Layout]
    expects: str  # "solvable", "unsolvable" or "either"


_FAMILY_LIST = (
    _Family("scattered", "3-7 boxes of the seed's sizes near the way, some unknown", _scattered, "solvable"),
    _Family(
        "wall_gap",
        "a full-height divider wall with a gap or a door open at 70-90°; the wall or the door leaf often unknown",
        _wall_gap,
        "solvable",
    ),
    _Family(
        "corridor",
        "a corridor 0.42-0.60 m wide, open or the only way through; some walls unknown",
        _corridor,
        "solvable",
    ),
    _Family("trap_l", "an L-shaped dead end facing the start, often unknown", _trap_l, "solvable"),
    _Family(
        "trap_u",
        "a U-shaped dead end facing the start (the seed's large obstacles), often unknown",
        _trap_u,
        "solvable",
    ),
    _Family(
        "clutter",
        "12-22 small boxes and round posts, most unknown, most along the way, as dense as leaves a way",
        _clutter,
        "solvable",
    ),
    _Family(
        "narrow_passage",
        "the only passage 2 × inflation to 2 × inflation + 6 cm wide; solvable or not by where the grid's cells fall",
        _narrow_passage,
        "either",
    ),
    _Family("unknown_on_path", "unknown boxes across the optimal path of the known map", _unknown_on_path, "solvable"),
    _Family(
        "unknown_near_start", "an unknown box just beyond the inflation from the start", _unknown_near_start, "solvable"
    ),
    _Family(
        "unknown_near_target",
        "an unknown box just beyond the inflation from the target",
        _unknown_near_target,
        "solvable",
    ),
    _Family(
        "unknown_against_wall",
        "unknown boxes flush against the arena's walls, one beside the way",
        _unknown_against_wall,
        "solvable",
    ),
    _Family(
        "out_and_back", "out to the target and back (one trip) past known and unknown boxes", _out_and_back, "solvable"
    ),
    _Family(
        "unreachable",
        "the target enclosed (free, but walled in): the answer is 'unreachable'",
        _unreachable,
        "unsolvable",
    ),
    _Family("start_at_target", "the target 2-5 cm from the start", _start_at_target, "solvable"),
)
#: Families drawn only when asked for by name (--families): the default cycle, and so the arenas
#: of every seed drawn before they existed, stay as they were.
_EXTRA_FAMILY_LIST = (
    _Family(
        "cellular",
        "BARN's worlds scaled to this rover: 2.5-4 x 1.8-3 m, cells of 8.4 cm filled at random "
        "(10-30 %) and smoothed 0-4 times by a cellular automaton, every box "
        "unknown; a world without a way through is drawn again (by name only)",
        _cellular,
        "solvable",
    ),
)
FAMILIES: tuple[tuple[str, str], ...] = tuple((f.name, f.description) for f in _FAMILY_LIST + _EXTRA_FAMILY_LIST)
FAMILY_NAMES: tuple[str, ...] = tuple(f.name for f in _FAMILY_LIST)  # the default cycle
ALL_FAMILY_NAMES: tuple[str, ...] = FAMILY_NAMES + tuple(f.name for f in _EXTRA_FAMILY_LIST)
_BY_NAME = {f.name: f for f in _FAMILY_LIST + _EXTRA_FAMILY_LIST}
