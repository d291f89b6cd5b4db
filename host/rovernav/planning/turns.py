"""Turns the rover's body can make: the on-the-spot turns a path asks for at its waypoints.

Where its path bends by more than a few degrees the rover stops and turns on the spot, and its
corners sweep a circle of the body's half-diagonal round the waypoint (0.129 m for the seed's
0.15 x 0.21 m body: protocol/vehicle.toml). That is wider than the robot radius the
planner keeps from obstacles (0.12 m): a path that bends just past the end of a wall, as A*'s
shortest paths do, asks for a turn the corners cannot make (seed 1's arena 189, where the rover
turned its front corner into the end of a divider it had passed).

`turnable` moves each such waypoint to the nearest point round it (within `SEARCH_M`) whose
circle is clear of every obstacle the grid holds, known or seen by the sonar (its raw cells and
the arena's wall), and whose two legs stay on the planner's free cells; the start and the
target stay where they are. Where no such point is near, the waypoint stays: the rover's own
check (room_to_turn) backs it out before it turns.

The turn at the start, from the heading the rover has to the path's first leg, is checked too
when the heading is given: where the rover stands with no room to turn, a point straight ahead
where it has room (reached without turning) goes in first. The rover's own memory forgets what
slips behind its centre; the host's map does not (cellular seed 2612's arena 60: a turn on the
spot beside a box seen 18 s before). Where no point ahead has room the path stays as it is.

What only the sonar has seen is half seen: an echo shows the face the burst met, and the
obstacle runs on behind it by an unknown depth. `half_seen` marks HALF_SEEN_DEPTH_M behind each
occupied cell of an echo's arc, along the beam, for the turn checks (arena 60's box was 8 cm
deep; its face was 19 cm from where the rover turned, its far side 11 cm).

`body_clear` checks a straight drive against the same map with the body's half width: the line
on from where a rover stopped backing out (rovernav.mission.strategies).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from ..angles import wrap_rad
from ..link.messages_gen import PARAMS, Param
from ..vehicle_gen import BACK_OFF_MM, BODY_LENGTH_MM, BODY_WIDTH_MM
from .grid import OccupancyGrid

#: The corners' reach from the centre as the rover turns on the spot [m]: the half-diagonal.
SWING_M = math.hypot(BODY_LENGTH_MM, BODY_WIDTH_MM) / 2000.0
#: What the turn wobbles by, and a raw cell's centre from its nearest point, on top [m].
SWING_MARGIN_M = 0.01
#: Turns smaller than this barely swing the corners (the firmware's kBackOffMinTurnDeg) [deg].
MIN_TURN_DEG = 20.0
#: How far a waypoint may move to find room for its turn [m].
SEARCH_M = 0.3
#: The rover's arrival radius unless the mission says what it configured (arrival_radius_mm's
#: default): a point put in straight ahead for the first turn lies beyond it and the margin, since
#: a nearer one counts as reached where the rover stands, and it turns there after all (a fleet
#: rover's 30 mm point, then its side along a corner) [m].
ARRIVAL_M = PARAMS[Param.ARRIVAL_RADIUS_MM].default / 1000.0
#: A turn this near where the rover refused one (TURN_REFUSED: its own memory said its corners
#: would hit) has no room, whatever the grid says: a refusal comes within the arrival radius
#: (36 mm) of the waypoint, and the waypoint may have moved a cell since [m].
REFUSED_NEAR_M = 0.06
#: The rover at its path's start this near a spot where it refused a turn has no room for it
#: there (`ahead_first`): the host's STOP may land while it backs out, up to the back-off
#: distance (0.15 m) from where it refused [m].
REFUSED_HERE_M = BACK_OFF_MM / 1000.0 + 0.01
#: What an echo leaves unseen behind the face it shows, along the beam [m]: the smallest box the
#: arena generators make (8 cm); the half body width.
HALF_SEEN_DEPTH_M = 0.08


def half_seen(
    grid: OccupancyGrid, echoes: Sequence, sonar_offset_m: float, cone_deg: float, depth_m: float = HALF_SEEN_DEPTH_M
) -> np.ndarray:
    """Cells [ny, nx] within depth_m behind each occupied cell of an echo's arc, along the beam.

    echoes: anything with x_m, y_m, heading_deg, bearing_deg and range_m (rovernav.mapping.learned_map.Echo),
    the rover's pose when it pinged; the arc is sampled across the cone, and only where the grid
    holds an obstacle (an arc the sonar has since seen clear casts nothing).
    """
    mask = np.zeros((grid.ny, grid.nx), dtype=np.bool_)
    rows = [
        (e.x_m, e.y_m, e.heading_deg + e.bearing_deg, e.range_m, e.heading_deg)
        for e in echoes
        if e.range_m is not None and e.range_m > 0
    ]
    if not rows or depth_m <= 0:
        return mask
    a = np.asarray(rows, dtype=np.float64)
    h = np.radians(a[:, 4])
    sx = a[:, 0] + sonar_offset_m * np.sin(h)
    sy = a[:, 1] + sonar_offset_m * np.cos(h)
    res = grid.resolution_m
    across = np.radians(np.linspace(-cone_deg / 2, cone_deg / 2, 5))
    axis = np.radians(a[:, 2])[:, None] + across[None, :]  # [echo, ray]
    ux, uy = np.sin(axis), np.cos(axis)
    r = a[:, 3][:, None]
    ix = np.floor((sx[:, None] + r * ux) / res).astype(np.int64)
    iy = np.floor((sy[:, None] + r * uy) / res).astype(np.int64)
    inside = (ix >= 0) & (ix < grid.nx) & (iy >= 0) & (iy < grid.ny)
    hit = np.zeros_like(inside)
    hit[inside] = grid.raw[iy[inside], ix[inside]]
    if not hit.any():
        return mask
    steps = np.arange(1, int(math.ceil(depth_m / (res / 2))) + 1) * min(res / 2, depth_m)
    e, k = np.nonzero(hit)
    d = r[e, 0][:, None] + steps[None, :]  # [hit, step]
    px = sx[e][:, None] + d * ux[e, k][:, None]
    py = sy[e][:, None] + d * uy[e, k][:, None]
    jx = np.floor(px / res).astype(np.int64).ravel()
    jy = np.floor(py / res).astype(np.int64).ravel()
    ok = (jx >= 0) & (jx < grid.nx) & (jy >= 0) & (jy < grid.ny)
    mask[jy[ok], jx[ok]] = True
    return mask


def clearance_map(grid: OccupancyGrid, reach_m: float = 1.0, hidden: np.ndarray | None = None) -> np.ndarray:
    """Distance [m] from each cell centre to the nearest obstacle or the arena's wall (inf past reach_m).

    Exact to the known obstacles' geometry (boxes, walls, posts); to the cells only the sonar has
    filled (raw cells no known obstacle overlaps), and to the `hidden` ones (half_seen), from
    their centres less half a cell.
    """
    exact = grid.obstacle_distance(reach_m)
    seen = grid.raw & (exact > grid.resolution_m * math.sqrt(0.5))  # no known obstacle explains them
    if hidden is not None:
        seen = seen | (hidden & (exact > grid.resolution_m * math.sqrt(0.5)))
    if seen.any():
        to_seen = cv2.distanceTransform((~seen).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        exact = np.minimum(exact, np.maximum(to_seen.astype(np.float64) - 0.5, 0.0) * grid.resolution_m)
    return np.minimum(exact, grid.wall_distance())


def turn_deg(a: Sequence[float], b: Sequence[float], c: Sequence[float]) -> float:
    """The turn [deg, 0..180] at b of the path a -> b -> c."""
    h1 = math.atan2(b[0] - a[0], b[1] - a[1])  # headings: 0 up the arena, clockwise positive
    h2 = math.atan2(c[0] - b[0], c[1] - b[1])
    return abs(math.degrees(wrap_rad(h2 - h1)))


def _room(clear: np.ndarray, grid: OccupancyGrid, p: Sequence[float]) -> float:
    ix, iy = grid.world_to_cell(p[0], p[1])
    return float(clear[iy, ix])


def _refused_near(p: Sequence[float], refused: Sequence[Sequence[float]]) -> bool:
    return any(math.dist(p, r) <= REFUSED_NEAR_M for r in refused)


def refused_turn(
    waypoints: Sequence[Sequence[float]], refused: Sequence[Sequence[float]]
) -> tuple[float, float] | None:
    """Where the path asks for a turn (of more than MIN_TURN_DEG, at a waypoint between its ends)
    near a spot where the rover refused one; None when it does not."""
    pts = [(float(x), float(y)) for x, y in waypoints]
    for i in range(1, len(pts) - 1):
        if turn_deg(pts[i - 1], pts[i], pts[i + 1]) > MIN_TURN_DEG and _refused_near(pts[i], refused):
            return pts[i]
    return None


def turnable(
    grid: OccupancyGrid,
    waypoints: Sequence[Sequence[float]],
    refused: Sequence[Sequence[float]] = (),
    hidden: np.ndarray | None = None,
) -> tuple[list[tuple[float, float]], int, int]:
    """The path with each waypoint whose turn the body cannot make moved where it can.

    A waypoint near a spot in `refused` (where the rover refused a turn) has no room either;
    `hidden` (half_seen) counts as obstacle. Returns (waypoints, moved, left): how many waypoints
    were moved, and how many still ask for a turn without room (none near had room and clear legs).
    """
    pts = [(float(x), float(y)) for x, y in waypoints]
    if len(pts) < 3:
        return pts, 0, 0
    need = SWING_M + SWING_MARGIN_M
    res = grid.resolution_m
    clear = clearance_map(grid, reach_m=need + res, hidden=hidden)  # only whether there is room matters
    # Candidate offsets: every cell's step within SEARCH_M (tried for the least added length).
    k = int(SEARCH_M / res)
    offs = [
        (dx * res, dy * res) for dx in range(-k, k + 1) for dy in range(-k, k + 1) if 0 < dx * dx + dy * dy <= k * k
    ]
    moved = 0
    stuck: set[int] = set()
    # A moved waypoint changes the turn at the one before it: look again, until nothing moves.
    for _ in range(3):
        changed = False
        for i in range(1, len(pts) - 1):
            a, b, c = pts[i - 1], pts[i], pts[i + 1]
            if turn_deg(a, b, c) <= MIN_TURN_DEG or (_room(clear, grid, b) >= need and not _refused_near(b, refused)):
                stuck.discard(i)
                continue
            q = _nearest_room(grid, clear, need, offs, a, b, c, refused)
            if q is None:
                stuck.add(i)
                continue
            pts[i] = q
            stuck.discard(i)
            moved += 1
            changed = True
        if not changed:
            break
    return pts, moved, len(stuck)


def ahead_first(
    grid: OccupancyGrid,
    waypoints: Sequence[Sequence[float]],
    heading_deg: float,
    hidden: np.ndarray | None = None,
    arrival_m: float = ARRIVAL_M,
    refused_at: Sequence[Sequence[float]] = (),
) -> tuple[list[tuple[float, float]], int]:
    """The turn at the path's first point, where the rover stands facing heading_deg.

    When that turn is more than MIN_TURN_DEG and the corners have no room there (the grid's
    obstacles, known and seen, and `hidden`), the nearest point straight ahead (`points_ahead`)
    whose leg to the next waypoint is clear goes in after it: the rover drives there without
    turning, and turns there. Returns (points, 1) with it, (points, -1) when there is none,
    (points, 0) when the turn needs no room.

    `refused_at`: where the rover refused a turn in this leg (TURN_REFUSED). Within
    REFUSED_HERE_M of one the rover's own check has said there is no room, whatever the grid says:
    a fleet's rover, stopped by the host as it began to back out, is planned afresh from there,
    and the same turn sent again would be refused again. No point ahead that near one is taken
    either.
    """
    pts = [(float(x), float(y)) for x, y in waypoints]
    if len(pts) < 2 or not first_turn_tight(grid, pts, heading_deg, hidden, refused_at):
        return pts, 0
    for q in points_ahead(grid, pts[0], heading_deg, hidden, arrival_m, refused_at):
        if grid.segment_clear(q, pts[1]):
            return [pts[0], q] + pts[1:], 1
    return pts, -1


def first_turn_tight(
    grid: OccupancyGrid,
    pts: Sequence[Sequence[float]],
    heading_deg: float,
    hidden: np.ndarray | None = None,
    refused_at: Sequence[Sequence[float]] = (),
) -> bool:
    """Whether the turn from heading_deg onto the path's first leg is more than MIN_TURN_DEG
    where the corners have no room (or the rover refused one, see ahead_first)."""
    p0, p1 = pts[0], pts[1]
    leg = math.atan2(p1[0] - p0[0], p1[1] - p0[1])
    turn = abs(math.degrees(wrap_rad(leg - math.radians(heading_deg))))
    refused_here = any(math.dist(p0, r) <= REFUSED_HERE_M for r in refused_at)
    # Near a refusal, a turn a little under MIN_TURN_DEG counts too: the rover's heading and the
    # camera's differ by a few degrees, and the rover refuses what it makes more than that.
    if turn <= (MIN_TURN_DEG / 2 if refused_here else MIN_TURN_DEG) or not grid.contains(*p0):
        return False
    if refused_here:
        return True
    clear = clearance_map(grid, reach_m=SWING_M + SWING_MARGIN_M + grid.resolution_m, hidden=hidden)
    return _room(clear, grid, p0) < SWING_M + SWING_MARGIN_M


def points_ahead(
    grid: OccupancyGrid,
    p0: Sequence[float],
    heading_deg: float,
    hidden: np.ndarray | None = None,
    arrival_m: float = ARRIVAL_M,
    refused_at: Sequence[Sequence[float]] = (),
) -> list[tuple[float, float]]:
    """The points straight ahead of a rover at p0 facing heading_deg, nearest first (within
    SEARCH_M, a cell at a time), where it has room to turn: beyond its arrival radius `arrival_m`
    and the margin (a nearer one counts as reached where the rover stands), on a free cell, not
    within REFUSED_HERE_M of where it refused a turn (its own memory said no room there, and it
    may hold what the host's map does not: echoes of other rovers), and reached with the body's sides clear of the way (by half its
    width and the margin, or, where the rover already stands nearer than that, by no less than
    where it stands)."""
    need = SWING_M + SWING_MARGIN_M
    res = grid.resolution_m
    clear = clearance_map(grid, reach_m=need + res, hidden=hidden)
    h = math.radians(heading_deg)
    side = min(BODY_WIDTH_MM / 2000.0 + SWING_MARGIN_M, _room(clear, grid, p0))
    ux, uy = math.sin(h), math.cos(h)
    out = []
    for k in range(1, int(SEARCH_M / res) + 1):
        q = (p0[0] + k * res * ux, p0[1] + k * res * uy)
        if not grid.contains(*q):
            break
        if _room(clear, grid, q) < side:
            break  # the sides would scrape on the way: nothing further on is reached either
        # (A rover standing inside the planner's margin drives out of it before a point is free.)
        beyond = k * res >= arrival_m + SWING_MARGIN_M
        near_refusal = any(math.dist(q, r) <= REFUSED_HERE_M for r in refused_at)
        if beyond and _room(clear, grid, q) >= need and not near_refusal and grid.is_free(*q):
            out.append(q)
    return out


def backed_out_clear(
    grid: OccupancyGrid,
    p: Sequence[float],
    heading_deg: float,
    next_point: Sequence[float],
    hidden: np.ndarray | None = None,
) -> bool:
    """Whether, having backed straight out the whole back-off distance from p (facing
    heading_deg), the rover has room there for its turn and a clear drive on to next_point: it
    turns there without looking (its check was made before it backed out), and the line on is a
    line no planner chose (the crash of fleet seed 2 at the corner of the box the sonar finds)."""
    h = math.radians(heading_deg)
    b = (p[0] - BACK_OFF_MM / 1000.0 * math.sin(h), p[1] - BACK_OFF_MM / 1000.0 * math.cos(h))
    if not grid.contains(*b):
        return False
    res = grid.resolution_m
    clear = clearance_map(grid, reach_m=SWING_M + SWING_MARGIN_M + res, hidden=hidden)
    return _room(clear, grid, b) >= SWING_M + SWING_MARGIN_M and body_clear(grid, b, next_point)


def room_behind(grid: OccupancyGrid, p: Sequence[float], heading_deg: float, hidden: np.ndarray | None = None) -> bool:
    """Whether the rover, standing at p facing heading_deg, can back straight out the whole
    back-off distance (BACK_OFF_MM) without its body meeting what the grid holds (known and
    seen, and `hidden`): its centre line keeps the body's half width clear, out to its tail at
    the end (or, where the rover already stands nearer than that, no less than where it stands). The host asks for a back-out (PATH back_out) only then: twice
    the rover backed the whole way on the host's word into a known box behind it (fleet seeds 2
    and 3)."""
    res = grid.resolution_m
    if not grid.contains(*p):
        return False
    clear = clearance_map(grid, reach_m=BODY_WIDTH_MM / 2000.0 + SWING_MARGIN_M + res, hidden=hidden)
    side = min(BODY_WIDTH_MM / 2000.0 + SWING_MARGIN_M, _room(clear, grid, p))
    h = math.radians(heading_deg)
    ux, uy = math.sin(h), math.cos(h)
    # Disks of radius `side` along the centre line cover the body's swath, out to its tail (and the margin) at the end.
    reach_m = (BACK_OFF_MM + BODY_LENGTH_MM / 2) / 1000.0 + SWING_MARGIN_M - side
    for k in range(1, int(math.ceil(reach_m / res)) + 1):
        q = (p[0] - k * res * ux, p[1] - k * res * uy)
        if not grid.contains(*q) or _room(clear, grid, q) < side:
            return False
    return True


def _nearest_room(
    grid: OccupancyGrid,
    clear: np.ndarray,
    need: float,
    offs: list[tuple[float, float]],
    a: tuple[float, float],
    b: tuple[float, float],
    c: tuple[float, float],
    refused: Sequence[Sequence[float]] = (),
) -> tuple[float, float] | None:
    """The point near b, for the least added length, with room to turn (or little turn to make)
    and clear legs from a and to c; None when there is none within SEARCH_M."""
    base = math.dist(a, b) + math.dist(b, c)
    options = []
    for dx, dy in offs:
        q = (b[0] + dx, b[1] + dy)
        if not grid.contains(*q) or not grid.is_free(*q):
            continue
        if (_room(clear, grid, q) < need or _refused_near(q, refused)) and turn_deg(a, q, c) > MIN_TURN_DEG:
            continue
        options.append((math.dist(a, q) + math.dist(q, c) - base, q))
    options.sort()
    for _, q in options:
        if grid.segment_clear(a, q) and grid.segment_clear(q, c):
            return q
    return None


def body_clear(grid: OccupancyGrid, a: Sequence[float], b: Sequence[float]) -> bool:
    """Whether the body's sides clear every obstacle the grid holds (known, seen by the sonar, and
    the arena's wall) as the rover drives straight from a to b [m]: the clearance of its centre,
    every half cell along the way, at least half its width and SWING_MARGIN_M."""
    side = BODY_WIDTH_MM / 2000.0 + SWING_MARGIN_M
    res = grid.resolution_m
    clear = clearance_map(grid, reach_m=side + res)
    n = max(1, int(math.ceil(math.dist(a, b) / (res / 2))))
    for k in range(n + 1):
        p = (a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n)
        if not grid.contains(*p) or _room(clear, grid, p) < side:
            return False
    return True
