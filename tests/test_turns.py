"""The turns a path asks for at its waypoints: the host moves a bend where the body's corners
cannot swing (rovernav.planning.turns)."""

from __future__ import annotations

import math

import numpy as np

from rovernav.link import messages_gen as mg
from rovernav.mapping.learned_map import Echo
from rovernav.planning import OccupancyGrid, PlannerConfig, plan
from rovernav.planning.turns import (
    HALF_SEEN_DEPTH_M,
    MIN_TURN_DEG,
    REFUSED_NEAR_M,
    SWING_M,
    SWING_MARGIN_M,
    ahead_first,
    backed_out_clear,
    body_clear,
    clearance_map,
    half_seen,
    room_behind,
    turn_deg,
    turnable,
)

# A divider up from the bottom edge, its end 0.48 m below the top: the way from one side to the
# other bends round its end.
WALL = (1.453, 0.0, 1.453, 1.55, 0.054)


def _wall_distance(p: tuple[float, float]) -> float:
    """Exact distance [m] from p to the divider's rectangle."""
    x0, x1 = WALL[0] - WALL[4] / 2, WALL[0] + WALL[4] / 2
    dx = max(x0 - p[0], 0.0, p[0] - x1)
    dy = max(WALL[1] - p[1], 0.0, p[1] - WALL[3])
    return math.hypot(dx, dy)


def _grid(margin_m: float) -> OccupancyGrid:
    g = OccupancyGrid(2.94, 2.03, PlannerConfig(sonar_margin_m=margin_m))
    g.add_wall(*WALL)
    return g


def _tight_turns(path) -> list[int]:
    need = SWING_M + SWING_MARGIN_M
    return [
        i
        for i in range(1, len(path) - 1)
        if turn_deg(*path[i - 1 : i + 2]) > MIN_TURN_DEG and _wall_distance(path[i]) < need
    ]


def _echo_grid() -> tuple[OccupancyGrid, np.ndarray]:
    """The divider as only the sonar has seen it: its west face's cells, inflated by the robot
    radius alone (the mission's last try, `LearnedMap.lenient_grid`); returns the grid and the
    cells' centres [m]."""
    g = OccupancyGrid(2.94, 2.03, PlannerConfig(sonar_margin_m=0.0))
    ix = int(1.43 / g.resolution_m)
    rows = np.arange(0, int(1.55 / g.resolution_m))
    g.raw[rows, ix] = True
    d = np.hypot(g.xs[None, :] - g.xs[ix], np.maximum(np.abs(g.ys[:, None] - 0.775) - 0.775, 0.0))
    g.inflated |= d <= g.config.robot_radius_m
    return g, np.column_stack([np.full(len(rows), g.xs[ix]), g.ys[rows]])


def _tight_echo_turns(path, centres: np.ndarray, res: float) -> list[int]:
    need = SWING_M + SWING_MARGIN_M
    return [
        i
        for i in range(1, len(path) - 1)
        if turn_deg(*path[i - 1 : i + 2]) > MIN_TURN_DEG
        and np.hypot(*(centres - np.asarray(path[i])).T).min() - res / 2 < need
    ]


def test_a_bend_round_what_the_sonar_saw_moves_where_the_corners_swing_clear():
    # With the robot radius alone (0.12 m from the echoes' cells) A*'s path bends within the
    # half-diagonal (0.129 m) of the divider's end, whose unseen part may reach on behind.
    g, centres = _echo_grid()
    raw = plan(g, (1.3, 1.2), (1.7, 1.0)).waypoints
    assert _tight_echo_turns(raw, centres, g.resolution_m), "the test's premise: a bend without room"
    path, moved, left = turnable(g, raw)
    assert moved >= 1 and left == 0
    assert _tight_echo_turns(path, centres, g.resolution_m) == []
    assert path[0] == raw[0] and path[-1] == raw[-1]  # the start and the target stay
    assert not g.path_blocked(path)  # every leg still on free cells
    added = sum(map(math.dist, path, path[1:])) - sum(map(math.dist, raw, raw[1:]))
    assert 0.0 <= added < 0.1


def test_a_known_walls_end_is_measured_exactly():
    # The same divider known: its geometry, not its cells. With the radius alone the bends keep
    # 0.145 m or more from it, room enough: nothing moves.
    g = _grid(0.0)
    raw = plan(g, (1.2, 1.3), (1.8, 0.9)).waypoints
    assert _tight_turns(raw) == []
    assert turnable(g, raw)[1:] == (0, 0)


def test_a_path_with_room_for_its_turns_is_left_as_it_is():
    g = _grid(0.05)  # the full margin: every bend 0.17 m from the divider
    raw = plan(g, (1.2, 1.3), (1.8, 0.9)).waypoints
    path, moved, left = turnable(g, raw)
    assert (moved, left) == (0, 0)
    assert path == [tuple(p) for p in raw]


def test_a_bend_with_no_room_near_stays_and_is_counted():
    # A passage the body barely fits, the bend in its middle: nowhere within reach has room.
    g = OccupancyGrid(1.0, 1.0, PlannerConfig(sonar_margin_m=0.0))
    g.add_box(0.5, 0.2, 1.0, 0.1)  # floor of a corridor 0.26 m high (centres at y 0.38)
    g.add_box(0.5, 0.56, 1.0, 0.1)
    path = [(0.15, 0.38), (0.5, 0.38), (0.85, 0.40)]
    assert turn_deg(*path) < MIN_TURN_DEG
    assert turnable(g, path)[1:] == (0, 0)  # too small a turn to check
    sharp = [(0.15, 0.38), (0.5, 0.38), (0.6, 0.45)]
    out, moved, left = turnable(g, sharp)
    assert (moved, left) == (0, 1) and out == sharp


def _box_grid() -> OccupancyGrid:
    # A known box 0.25 m square, its lower right corner at (0.785, 1.555) (seed 1's arena 193).
    g = OccupancyGrid(2.94, 2.03, PlannerConfig())
    g.add_box(0.66, 1.68, 0.25, 0.25)
    return g


def test_body_clear_tells_a_line_past_a_corner_from_one_into_it():
    g = _box_grid()
    assert body_clear(g, (1.0, 1.3), (1.8, 1.3))  # 0.255 m below the box: clear
    assert not body_clear(g, (0.6, 1.3), (0.9, 1.6))  # through the corner
    assert not body_clear(g, (0.82, 1.50), (1.2, 1.50))  # 0.055 m below the corner: a side scrapes


def test_a_turn_where_the_rover_refused_one_has_no_room():
    # The bend at (0.5, 0.5) has room on the grid; the rover refused a turn 3 cm from it (its
    # memory said its corners would hit): the bend moves, or is counted as without room.
    g = OccupancyGrid(1.0, 1.0, PlannerConfig())
    path = [(0.2, 0.5), (0.5, 0.5), (0.5, 0.8)]
    assert turnable(g, path)[1:] == (0, 0)
    out, moved, left = turnable(g, path, refused=[(0.52, 0.49)])
    assert moved == 1 and left == 0
    assert math.dist(out[1], (0.52, 0.49)) > REFUSED_NEAR_M
    assert not g.path_blocked(out)


# ---------------------------------------------------------------- half seen, and the first turn


def _box_face_grid() -> tuple[OccupancyGrid, Echo]:
    """An 8 cm box's south face at y = 1.71 m (x 1.93-2.01) as one echo heard from below
    (cellular seed 2612's arena 60): the rover 0.45 m south of it, looking north."""
    g = OccupancyGrid(3.0, 2.5, PlannerConfig(sonar_margin_m=0.0))
    echo = Echo(x_m=1.97, y_m=1.16, heading_deg=0.0, bearing_deg=0.0, range_m=0.45)
    sx, sy = 1.97, 1.16 + g.config.sonar_offset_m
    ix, iy = g.world_to_cell(sx, sy + 0.45)
    g.raw[iy, ix - 1 : ix + 2] = True  # the arc's cells
    return g, echo


def test_what_an_echo_hides_lies_behind_its_face_along_the_beam():
    g, echo = _box_face_grid()
    hidden = half_seen(g, [echo], g.config.sonar_offset_m, g.config.sonar_cone_deg)
    ys = g.ys[np.nonzero(hidden.any(axis=1))[0]]
    face_y = 1.16 + g.config.sonar_offset_m + 0.45
    assert ys.min() > face_y - g.resolution_m  # nothing in front of the face
    assert face_y + HALF_SEEN_DEPTH_M - g.resolution_m <= ys.max() <= face_y + HALF_SEEN_DEPTH_M + g.resolution_m
    xs = g.xs[np.nonzero(hidden.any(axis=0))[0]]
    assert xs.min() > 1.85 and xs.max() < 2.09  # within the cone's width there
    # An arc the sonar has since seen clear (its cells no longer held) casts nothing.
    g.raw[:] = False
    assert not half_seen(g, [echo], g.config.sonar_offset_m, g.config.sonar_cone_deg).any()


def test_the_hidden_depth_takes_room_from_a_turn_beside_the_face():
    # The rover stands north of the box, 0.19 m from the face it saw, 0.11 m from its far side:
    # room by the face alone, none with what the face hides.
    g, echo = _box_face_grid()
    hidden = half_seen(g, [echo], g.config.sonar_offset_m, g.config.sonar_cone_deg)
    need = SWING_M + SWING_MARGIN_M
    here = (1.965, 1.71 + 0.19)
    ix, iy = g.world_to_cell(*here)
    assert clearance_map(g, need + 0.1)[iy, ix] >= need
    assert clearance_map(g, need + 0.1, hidden=hidden)[iy, ix] < need


def test_no_room_to_turn_where_the_rover_stands_puts_a_point_straight_ahead_first():
    g, echo = _box_face_grid()
    hidden = half_seen(g, [echo], g.config.sonar_offset_m, g.config.sonar_cone_deg)
    start, heading = (1.965, 1.90), -90.0  # facing west, the box beside its left rear
    path = [start, (1.55, 2.2)]  # the next leg asks for a turn of about 125 degrees
    out, ahead = ahead_first(g, path, heading, hidden)
    assert ahead == 1 and len(out) == 3 and out[0] == start and out[-1] == path[-1]
    q = out[1]
    assert abs(q[1] - start[1]) < 1e-9 and 0.0 < start[0] - q[0] <= 0.3  # straight ahead, west
    clear = clearance_map(g, 1.0, hidden=hidden)
    assert clear[g.world_to_cell(*q)[1], g.world_to_cell(*q)[0]] >= SWING_M + SWING_MARGIN_M
    # Room a cell ahead (0.03 m): the point goes beyond the arrival radius, or the rover would count
    # it reached where it stands and turn there after all.
    near = (1.85, 1.90)
    out, ahead = ahead_first(g, [near, path[-1]], heading, hidden)
    arrival = mg.PARAMS[mg.Param.ARRIVAL_RADIUS_MM].default / 1000.0
    assert ahead == 1 and arrival < near[0] - out[1][0] <= 0.3
    # The same turn with the box known to be only its face: room where it stands, nothing added.
    assert ahead_first(g, path, heading)[1] == 0
    # A small turn needs no room; facing a wall close ahead there is no point to go to.
    assert ahead_first(g, [start, (1.5, 1.95)], heading, hidden)[1] == 0
    g.add_wall(1.90, 1.5, 1.90, 2.3, 0.02)
    assert ahead_first(g, path, heading, hidden) == (path, -1)


def test_the_host_asks_a_rover_to_back_out_only_where_its_map_has_room_straight_behind_it():
    # Facing east at (1.0, 0.6) in an empty arena: room to back out 0.15 m west. A box whose face
    # stands 0.20 m behind its centre (the tail 0.105 m behind it, backed 0.15 m: 0.255 m) is in
    # the way; 0.30 m behind, it is not. Facing west, the same box is ahead: room behind.
    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    assert room_behind(g, (1.0, 0.6), 90.0)
    g.add_box(0.70, 0.6, 0.20, 0.30)  # x 0.60..0.80: its face 0.20 m behind
    assert not room_behind(g, (1.0, 0.6), 90.0)
    assert room_behind(g, (1.10, 0.6), 90.0)  # its face 0.30 m behind
    assert room_behind(g, (1.0, 0.6), -90.0)
    # Backing past the arena's wall is no room either.
    assert not room_behind(g, (2.20, 0.6), -90.0)


def test_where_the_rover_refused_a_turn_the_first_turn_has_no_room_whatever_the_grid_says():
    # An empty arena: room to turn anywhere. The rover refused a turn 0.08 m ahead of where it
    # stands (the host stopped it as it backed out): the turn there is put off to a point straight
    # ahead, clear of the spot it refused at; with none ahead (a wall), no point goes in.
    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    start, heading = (1.0, 0.6), 90.0  # facing east
    path = [start, (1.0, 1.2)]  # a left turn of 90 degrees
    assert ahead_first(g, path, heading) == (path, 0)
    refused = [(1.08, 0.6)]
    out, ahead = ahead_first(g, path, heading, refused_at=refused)
    assert ahead == 1 and out[0] == start and out[-1] == path[-1]
    assert out[1][0] > start[0] and abs(out[1][1] - start[1]) < 1e-9
    assert math.dist(out[1], refused[0]) > REFUSED_NEAR_M
    # Refused further than the back-off distance away: no bearing on where it stands now.
    assert ahead_first(g, path, heading, refused_at=[(1.2, 0.6)]) == (path, 0)
    g.add_wall(1.16, 0.3, 1.16, 0.9, 0.02)  # a wall 0.15 m ahead: nowhere ahead to turn
    assert ahead_first(g, path, heading, refused_at=refused) == (path, -1)


def test_a_back_out_needs_room_to_turn_where_it_ends_and_a_clear_line_on():
    # Facing east at (1.0, 0.6): backed out 0.15 m it stands at (0.85, 0.6) and turns there
    # without looking, then drives straight on to the next waypoint.
    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    assert backed_out_clear(g, (1.0, 0.6), 90.0, (0.85, 1.3))
    g.add_box(1.0, 0.95, 0.2, 0.2)  # y 0.85..1.05: beside the line on from (0.85, 0.6) to (1.0, 1.3)
    assert not backed_out_clear(g, (1.0, 0.6), 90.0, (1.0, 1.3))
    assert backed_out_clear(g, (1.0, 0.6), 90.0, (0.6, 1.3))  # a line on that passes it
    g.add_box(0.85, 0.45, 0.1, 0.06)  # its face 0.12 m from where it would turn: no room for the corners
    assert not backed_out_clear(g, (1.0, 0.6), 90.0, (0.6, 1.3))


def test_a_fleet_rover_with_no_room_to_turn_drives_straight_on_to_room_and_is_planned_from_there():
    # Facing west at (1.0, 0.6), a box's top 0.115 m below it: no room to turn. Backed out (east)
    # it would stand with no more room; the one point ahead with room, (0.7, 0.6), has no clear
    # line on to the path's next waypoint past the small box above. A lone rover's host asks it
    # to back out (its rover checks for itself, and the host replans when it has backed out); a
    # fleet's rover (refused_at given) drives straight on to the point and is planned from there.
    from rovernav.mapping import LearnedMap
    from rovernav.mission.leg_plan import plan_leg

    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    g.add_box(1.0, 0.44, 0.3, 0.1)
    g.add_box(0.95, 0.85, 0.1, 0.1)
    learned = LearnedMap(g)
    start, goal = (1.0, 0.6), (1.6, 0.9)

    def plan_it(refused_at):
        notes: list[str] = []
        path, _ = plan_leg(
            learned, start, goal, planner="astar", heading=-90.0, refused=[], say=notes.append, refused_at=refused_at
        )
        return path, notes

    lone, notes = plan_it(None)
    assert lone.back_out and "it backs out first" in notes[-1]
    fleet, notes = plan_it([])
    assert not getattr(fleet, "back_out", False) and "planned afresh from there" in notes[-1]
    assert fleet[0] == start and fleet[-1] == goal
    q = fleet[1]
    assert abs(q[1] - start[1]) < 1e-9 and q[0] < start[0]  # straight ahead, west
    assert clearance_map(g, 1.0)[g.world_to_cell(*q)[1], g.world_to_cell(*q)[0]] >= SWING_M + SWING_MARGIN_M
    assert not g.path_blocked(fleet[1:])


def test_near_a_refusal_a_turn_a_little_under_the_least_counts():
    from rovernav.planning.turns import first_turn_tight

    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    start = (1.0, 0.6)
    a = math.radians(90.0 - 15.0)  # a path 15 degrees left of the rover's heading (east)
    path = [start, (start[0] + 0.5 * math.sin(a), start[1] + 0.5 * math.cos(a))]
    assert not first_turn_tight(g, path, 90.0)  # room, and under MIN_TURN_DEG
    assert first_turn_tight(g, path, 90.0, refused_at=[start])  # it refused there: 15 degrees count
    assert not first_turn_tight(g, path, 90.0 - 10.0, refused_at=[start])  # 5 degrees never do


def test_what_stopped_the_reflex_keeps_the_full_margin_in_every_grid_the_leg_is_planned_on():
    # A point the rover's reflex met (the corner of a box only the sonar saw, say): the leg is
    # planned round it by the full margin and a cell, whatever grid the planning falls back to.
    from rovernav.mapping import LearnedMap
    from rovernav.mission.leg_plan import plan_leg, with_margin_round

    g = OccupancyGrid(2.36, 1.75, PlannerConfig())
    assert with_margin_round(g, []) is g and with_margin_round(None, [(1.0, 1.0)]) is None
    met = (1.2, 0.9)
    firm = with_margin_round(g, [met])
    assert firm is not g and firm.inflated.sum() > g.inflated.sum()
    reach = g.config.inflation_m + g.resolution_m
    assert not firm.is_free(met[0], met[1] + reach - 0.02) and firm.is_free(met[0], met[1] + reach + 0.04)
    assert g.is_free(*met)  # the map itself is left as it was

    def closest(path) -> float:
        return min(math.dist(met, p) for a, b in zip(path, path[1:]) for p in np.linspace(a, b, 50))

    def plan_it(stopped_by):
        path, _ = plan_leg(
            LearnedMap(g),
            (0.5, 0.9),
            (1.9, 0.9),
            planner="astar",
            heading=None,
            refused=[],
            say=lambda _t: None,
            stopped_by=stopped_by,
        )
        return path

    assert closest(plan_it(None)) < 0.03  # straight through it
    assert closest(plan_it([met])) >= g.config.inflation_m
