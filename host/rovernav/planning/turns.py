"""Turns the rover's body can make: the on-the-spot turns a path asks for at its waypoints.

Where its path bends by more than a few degrees the rover stops and turns on the spot, and its
corners sweep a circle of the body's half-diagonal round the waypoint (0.129 m for the seed's
0.15 x 0.21 m body: [body] in protocol/messages.toml). That is wider than the robot radius the
planner keeps from obstacles (0.12 m): a path that bends just past the end of a wall, as A*'s
shortest paths do, asks for a turn the corners cannot make (seed 1's arena 189, where the rover
turned its front corner into the end of a divider it had passed).

`turnable` moves each such waypoint to the nearest point round it (within `SEARCH_M`) whose
circle is clear of every obstacle the grid holds, known or seen by the sonar (its raw cells and
the arena's wall), and whose two legs stay on the planner's free cells; the start and the
target stay where they are. Where no such point is near, the waypoint stays: the rover's own
check (room_to_turn) backs it out before it turns.

`body_clear` checks a straight drive against the same map with the body's half width: the line
on from where a rover stopped backing out (rovernav.mission.strategies).
"""
from __future__ import annotations

import math
from typing import Sequence

import cv2
import numpy as np

from ..angles import wrap_rad
from ..link.messages_gen import BODY_LENGTH_MM, BODY_WIDTH_MM
from .grid import OccupancyGrid

#: The corners' reach from the centre as the rover turns on the spot [m]: the half-diagonal.
SWING_M = math.hypot(BODY_LENGTH_MM, BODY_WIDTH_MM) / 2000.0
#: What the turn wobbles by, and a raw cell's centre from its nearest point, on top [m].
SWING_MARGIN_M = 0.01
#: Turns smaller than this barely swing the corners (the firmware's kBackOffMinTurnDeg) [deg].
MIN_TURN_DEG = 20.0
#: How far a waypoint may move to find room for its turn [m].
SEARCH_M = 0.3
#: A turn this near where the rover refused one (TURN_REFUSED: its own memory said its corners
#: would hit) has no room, whatever the grid says: a refusal comes within the arrival radius
#: (36 mm) of the waypoint, and the waypoint may have moved a cell since [m].
REFUSED_NEAR_M = 0.06


def clearance_map(grid: OccupancyGrid, reach_m: float = 1.0) -> np.ndarray:
    """Distance [m] from each cell centre to the nearest obstacle or the arena's wall (inf past reach_m).

    Exact to the known obstacles' geometry (boxes, walls, posts); to the cells only the sonar has
    filled (raw cells no known obstacle overlaps), from their centres less half a cell.
    """
    exact = grid.obstacle_distance(reach_m)
    seen = grid.raw & (exact > grid.resolution_m * math.sqrt(0.5))   # no known obstacle explains them
    if seen.any():
        to_seen = cv2.distanceTransform((~seen).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        exact = np.minimum(exact, np.maximum(to_seen.astype(np.float64) - 0.5, 0.0) * grid.resolution_m)
    return np.minimum(exact, grid.wall_distance())


def turn_deg(a: Sequence[float], b: Sequence[float], c: Sequence[float]) -> float:
    """The turn [deg, 0..180] at b of the path a -> b -> c."""
    h1 = math.atan2(b[0] - a[0], b[1] - a[1])   # headings: 0 up the arena, clockwise positive
    h2 = math.atan2(c[0] - b[0], c[1] - b[1])
    return abs(math.degrees(wrap_rad(h2 - h1)))


def _room(clear: np.ndarray, grid: OccupancyGrid, p: Sequence[float]) -> float:
    ix, iy = grid.world_to_cell(p[0], p[1])
    return float(clear[iy, ix])


def _refused_near(p: Sequence[float], refused: Sequence[Sequence[float]]) -> bool:
    return any(math.dist(p, r) <= REFUSED_NEAR_M for r in refused)


def refused_turn(waypoints: Sequence[Sequence[float]], refused: Sequence[Sequence[float]]
                 ) -> tuple[float, float] | None:
    """Where the path asks for a turn (of more than MIN_TURN_DEG, at a waypoint between its ends)
    near a spot where the rover refused one; None when it does not."""
    pts = [(float(x), float(y)) for x, y in waypoints]
    for i in range(1, len(pts) - 1):
        if turn_deg(pts[i - 1], pts[i], pts[i + 1]) > MIN_TURN_DEG and _refused_near(pts[i], refused):
            return pts[i]
    return None


def turnable(grid: OccupancyGrid, waypoints: Sequence[Sequence[float]],
             refused: Sequence[Sequence[float]] = ()) -> tuple[list[tuple[float, float]], int, int]:
    """The path with each waypoint whose turn the body cannot make moved where it can.

    A waypoint near a spot in `refused` (where the rover refused a turn) has no room either.
    Returns (waypoints, moved, left): how many waypoints were moved, and how many still ask for
    a turn without room (none near had room and clear legs).
    """
    pts = [(float(x), float(y)) for x, y in waypoints]
    if len(pts) < 3:
        return pts, 0, 0
    need = SWING_M + SWING_MARGIN_M
    res = grid.resolution_m
    clear = clearance_map(grid, reach_m=need + res)   # only whether there is room matters
    # Candidate offsets: every cell's step within SEARCH_M (tried for the least added length).
    k = int(SEARCH_M / res)
    offs = [(dx * res, dy * res) for dx in range(-k, k + 1) for dy in range(-k, k + 1)
            if 0 < dx * dx + dy * dy <= k * k]
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


def _nearest_room(grid: OccupancyGrid, clear: np.ndarray, need: float, offs: list[tuple[float, float]],
                  a: tuple[float, float], b: tuple[float, float], c: tuple[float, float],
                  refused: Sequence[Sequence[float]] = ()) -> tuple[float, float] | None:
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
