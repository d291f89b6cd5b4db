"""A leg's path on what the host knows (`Mission.plan_from`): A* on the careful map, then on the
open one, each with the full margin and then with the robot radius alone; the turns moved where
the body can make them, and the first one checked from the heading the rover has where it stands.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ..mapping import LearnedMap
from ..planning import NoPathError, OccupancyGrid, Unreachable, plan
from ..planning.turns import (
    ARRIVAL_M,
    ahead_first,
    backed_out_clear,
    half_seen,
    points_ahead,
    room_behind,
    turnable,
)

#: How far from a goal that an echo's arc covers the last tries may end their plan [m].
GOAL_SHIFT_M = 0.06
#: A path whose start lies this near the rover starts where it stands: its first turn is made
#: from the rover's heading, and is checked for room (rovernav.planning.turns.ahead_first) [m].
START_NEAR_M = 0.05


def with_margin_round(grid: OccupancyGrid | None, points: list[tuple[float, float]] | None) -> OccupancyGrid | None:
    """A copy of `grid` with a post a cell across at each of `points`, kept clear by the full margin
    (robot radius and sonar margin) as every obstacle is (the grid itself when there are none). What
    stopped a rover's reflex on a path planned with the robot radius alone is no echo placed
    somewhere across a cone: the rover met it, and a gap it closes is no gap for that rover (fleet
    seed 6: the host sent the same squeeze past a box's corner after each sweep, and the rover,
    stopped there once, held still for good)."""
    if grid is None or not points:
        return grid
    g = grid.copy()
    for x, y in points:
        g.add_post(x, y, g.resolution_m)
    return g


class PlannedPath(list):
    """A path (waypoints [m]) that asks the rover to back out before its first turn on the spot
    (PATH back_out): the host's map has no room for its corners where it stands."""

    def __init__(self, points, back_out: bool = False) -> None:
        super().__init__(points)
        self.back_out = back_out


def plan_leg(
    learned_map: LearnedMap,
    start: tuple[float, float],
    goal: tuple[float, float],
    *,
    planner: str,
    heading: float | None,
    refused: list[tuple[float, float]],
    say: Callable[[str], None],
    arrival_m: float = ARRIVAL_M,
    refused_at: list[tuple[float, float]] | None = None,
    stopped_by: list[tuple[float, float]] | None = None,
) -> tuple[list[tuple[float, float]] | None, NoPathError | None]:
    """(path, None), or (None, the planner's most telling reason) when there is no path.

    From the nearest free cell when the rover stands inside an inflated margin (close to what it
    has just found), and, round what only the sonar has seen, with the robot radius alone (the
    log-odds map already places an echo anywhere across its cone, so the sonar's placement margin
    counts it twice). Each on the careful map first, then on the open map, whose silence also
    clears the cells the cone's edge only cuts (rovernav.mapping.learned_map): careful, open,
    careful with the radius alone, open with the radius alone. A target is unreachable only when
    the obstacles enclose it even then.

    heading: the rover's heading [deg] when the path starts where it stands, for its first turn
    (None: not checked); refused: spots where the rover refused a turn twice in this leg; say:
    what the planning did, in words, for the mission's events; arrival_m: the rover's arrival
    radius as configured (a point put in ahead for the first turn lies beyond it); refused_at:
    every spot where it refused a turn in this leg, for the first turn's check (ahead_first), and
    a back-out then only with room to turn where it ends and a clear line on (backed_out_clear);
    None: neither (a lone rover's host replans when it hears the rover has backed out);
    stopped_by: what stopped the rover's forward reflex in this leg (the echoes' points): every
    grid keeps the full margin round them, the robot radius alone too (`with_margin_round`).
    """
    reason = None
    lenient = with_margin_round(learned_map.lenient_grid(), stopped_by)
    opened: list = []
    careful = with_margin_round(learned_map.grid, stopped_by)
    cfg = careful.config
    echoes = learned_map.echoes

    def grids():
        # The careful map, then the open one (built only when the careful map found no way),
        # each with the full margin before either with the radius alone.
        yield careful
        opened.extend(with_margin_round(g, stopped_by) for g in learned_map.open_grids())
        yield opened[0] if opened else None
        yield lenient
        yield opened[1] if len(opened) > 1 else None

    # A goal the known obstacles leave free but an echo's arc covers (the home the rover left,
    # beside a box whose corner echoed at the cone's edge) is reached from the nearest free
    # cell within GOAL_SHIFT_M, in the last tries only: too short a way to pass any wall.
    goal_known_free = learned_map.known_grid.is_free(*goal)
    for grid in grids():
        if grid is None:
            continue
        last_tries = grid is lenient or (len(opened) > 1 and grid is opened[1])
        shifted = nearest_free(goal, grid, GOAL_SHIFT_M) if last_tries and goal_known_free else None
        for origin in (start, nearest_free(start, grid)):
            if origin is None:
                continue
            for end in (goal, shifted):
                if end is None:
                    continue
                try:
                    result = plan(grid, origin, end, planner=planner)
                except NoPathError as exc:
                    # The most telling reason: that no route joins them, over a blocked start.
                    if reason is None or isinstance(exc, Unreachable):
                        reason = exc
                    continue
                # Where a bend asks for a turn the body's corners cannot make, the bend moves; a
                # spot where the rover refused a turn twice in this leg (`refused`) has no room either.
                hidden = half_seen(grid, echoes, cfg.sonar_offset_m, cfg.sonar_cone_deg)
                waypoints, moved, left = turnable(grid, result.waypoints, refused, hidden)
                if grid is lenient:
                    say("planned with the robot radius alone round what only the sonar has seen")
                elif grid is not careful:
                    say("planned on the open map (silence clears the cone's edges too)")
                if end is not goal:
                    say(
                        f"the goal lies within an echo's arc: planned to "
                        f"{math.dist(end, goal) * 100:.0f} cm from it, then straight on"
                    )
                if moved or left:
                    say(
                        f"turns: moved {moved} waypoint{'s' if moved != 1 else ''} "
                        f"where the body can turn" + (f", {left} without room near" if left else "")
                    )
                path = [tuple(p) for p in waypoints] + ([] if end is goal else [tuple(goal)])
                path = path if origin is start else [start] + path
                if heading is not None:
                    # The first turn, from the heading the rover has where it stands.
                    path, ahead = ahead_first(grid, path, heading, hidden, arrival_m, refused_at or ())
                    if ahead > 0:
                        say("no room to turn where the rover stands: it drives straight on to turn first")
                    elif (
                        ahead < 0
                        and room_behind(grid, path[0], heading, hidden)
                        and (refused_at is None or backed_out_clear(grid, path[0], heading, path[1], hidden))
                    ):
                        # Its own memory may have let go of what the map holds: the path
                        # asks it to back out the way it came before it turns (PATH back_out).
                        path = PlannedPath(path, back_out=True)
                        say("no room to turn where the rover stands, none straight ahead: it backs out first")
                    elif (
                        ahead < 0
                        and refused_at is not None
                        and (
                            on := _on_from_ahead(
                                grid, path, heading, hidden, arrival_m, refused_at, refused, end, goal, planner
                            )
                        )
                    ):
                        path = on
                        say(
                            "no room to turn where the rover stands, none straight ahead on to its path, nor behind: "
                            "it drives straight on to a spot with room, planned afresh from there"
                        )
                    elif ahead < 0:
                        say(
                            "no room to turn where the rover stands, none straight ahead, nor behind with a clear "
                            "line on: it turns there"
                        )
                return path, None
    return None, reason


#: How many points straight ahead with room a rover with none where it stands is planned from.
AHEAD_PLANS = 4


def _on_from_ahead(grid, path, heading, hidden, arrival_m, refused_at, refused, end, goal, planner):
    """A rover with no room to turn where it stands, whose path's first leg no point straight
    ahead joins, nor a back-out: a path straight on to a point ahead with room (points_ahead,
    nearest first, AHEAD_PLANS of them) and planned afresh from there to `end`, where it turns
    (and `goal` after it when the plan ends short of it, as plan_leg's do) (None: none). Sent
    the path with its turn where it stands, the rover refuses it, backs out along its track of
    its own and turns where that ends, unchecked (fleet seed 7: a corner met the box the sonar
    finds)."""
    for q in points_ahead(grid, path[0], heading, hidden, arrival_m, refused_at)[:AHEAD_PLANS]:
        try:
            result = plan(grid, q, end, planner=planner)
        except NoPathError:
            continue
        waypoints, _moved, _left = turnable(grid, [path[0], *result.waypoints], refused, hidden)
        return [tuple(p) for p in waypoints] + ([] if end is goal else [tuple(goal)])
    return None


def nearest_free(xy: tuple[float, float], grid: OccupancyGrid, max_m: float = 0.3) -> tuple[float, float] | None:
    """A free point of `grid` within max_m of xy, nearest ring (a cell apart) first; None when xy
    is free itself, or nothing that near is."""
    if grid.is_free(*xy):
        return None  # the start itself is free: nothing nearer to try
    step = grid.resolution_m
    for ring in range(1, int(max_m / step) + 1):
        r = ring * step
        for k in range(max(8, ring * 8)):
            a = 2 * math.pi * k / max(8, ring * 8)
            p = (xy[0] + r * math.cos(a), xy[1] + r * math.sin(a))
            if grid.contains(*p) and grid.is_free(*p):
                return p
    return None
