"""Rovers as moving obstacles (issue 30): who drives and who waits, and what a rover plans round.

The host sees every rover in each camera frame and knows the path each is driving. Four rules,
in the order the rovers' ids give them (rover 1 first):

- **A path is planned round the rovers that stand still** (parked at a base or a site, or held):
  their bodies are drawn into the map the planner sees (`planning_map`), with the planner's own
  margin round them. Rovers on the move are not drawn in: they will be elsewhere.
- **A rover drives only while the stretch just ahead of it is clear** (`AHEAD_M` of its path):
  clear of every other rover's body, and of the stretch ahead of every rover before it in the
  order. Otherwise it is held where it is (STOP; its leg waits) and the others go on.
- **A held rover goes on** when its stretch has been clear for `CLEAR_FOR_S`, on its path; when
  it has waited `REPLAN_AFTER_S`, on a path planned round the rovers then in its way, if there is
  one. Only one held rover is let go a tick, the first in the order, so that two never pull out
  into each other. Rovers that have held each other round for `GIVE_WAY_AFTER_S` (two, each in
  the other's way, or three or more in a ring): the latest in the order gives way to the rover it
  holds, back along its own track or to the nearest free spot `SIDE_STEP_M` or so away, off that
  rover's path, and waits there (with the turn-care trial, until that rover, on the move, has
  passed: `GAVE_WAY_WAIT_S` at most). A rover that refused a turn (held at once with the trial:
  `FleetControl.hold_on_refused`) is left standing `REFUSED_SETTLE_S` before it goes on or gives
  way.
- **A rover parked** (its trips done, waiting for the fleet, at home or at a spot aside) that
  stands in the way of a rover with no way round it is sent aside, off that rover's way (with
  the trial, off the berths and sites of the rovers with trips to do, where it can be), and
  back home once no rover's way passes its berth.

The rover's own reflex still stops it for a rover its sonar sees; what it reports of another
rover is kept out of the shared map (`echo_is_rover`).
"""

from __future__ import annotations

import math

import numpy as np

from ..mapping import Echo
from ..mission.legs import path_length_m
from ..vehicle_gen import BODY_LENGTH_MM, BODY_WIDTH_MM

HALF_DIAGONAL_M = math.hypot(BODY_LENGTH_MM, BODY_WIDTH_MM) / 2000.0
#: Two rovers' centres nearer than this may touch (two half-diagonals and a margin) [m].
CLEAR_M = 2 * HALF_DIAGONAL_M + 0.04
#: The stretch of its path ahead of a rover that must be clear for it to drive [m].
AHEAD_M = 0.45
#: A held rover's stretch must be clear this long before it goes on [s].
CLEAR_FOR_S = 0.5
#: A held rover plans round what holds it after this long [s].
REPLAN_AFTER_S = 2.0
#: Two rovers that hold each other this long: the later in the order gives way [s].
GIVE_WAY_AFTER_S = 4.0
SIDE_STEP_M = 0.35
#: A rover that gave way waits (aside, or held on its way there) until the rover it gave way to
#: has passed (its way no longer comes near the giver's own stretch ahead), or this long at most
#: [s]: let go as soon as its own stretch was clear, it drove back into the other's way, and the
#: two gave way to each other for good (1 % loss, seed 2, with the berth rule).
GAVE_WAY_WAIT_S = 45.0
#: Where a parked rover may be sent aside: rings this far from its berth [m], in this many
#: directions, planning a way to at most ASIDE_MAX_PLANS of the free spots (nearest first); the
#: same spots for a rover that gives way with no track to back along. The outer two are tried
#: only when the inner ones have no spot: in a corridor that is, with the full margin, the only
#: way to other berths (by the left wall, past the berth at (0.30, 1.25)), every spot within
#: 0.9 m is on the way of the rover held, and loss1 seeds 2 and 4 stuck for good there.
ASIDE_RINGS_M = (0.35, 0.5, 0.7, 0.9, 1.1, 1.3)
ASIDE_DIRECTIONS = 16
ASIDE_MAX_PLANS = 24
#: ... by a way at most this many times as long as the spot is far (a long way round among boxes
#: and rovers is a drive of its own, with its sweeps and turns, not a step aside).
ASIDE_DETOUR = 2.0
TRACK_STEP_M = 0.04
TRACK_KEEP = 100  # points: 4 m of track a rover
#: A held rover tries a way round at most this often [s].
RETRY_S = 1.0
#: A moving rover's path drawn into another's planning map: a disk every this far along it [m].
LANE_STEP_M = 0.05
#: An echo this near another rover's centre is that rover [m].
ECHO_ON_ROVER_M = HALF_DIAGONAL_M + 0.08
#: Another rover drawn into a planning map: a disk that the planner's own margin (robot radius +
#: sonar margin, 0.17 m) grows to this far from its centre: a path planned round it is clear by
#: the rules' own distance, and a rover at a start 0.36 m from it is not shut in [m].
PLAN_CLEAR_M = CLEAR_M + 0.01


def _point_segment_m(p, a, b) -> float:
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    l2 = dx * dx + dy * dy
    t = 0.0 if l2 == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / l2))
    return math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy)


def polyline_point_m(line: list, p) -> float:
    """The distance from point p to a polyline (one point: to that point) [m]."""
    if len(line) == 1:
        return math.dist(line[0], p)
    return min(_point_segment_m(p, line[i], line[i + 1]) for i in range(len(line) - 1))


def polylines_m(a: list, b: list, step_m: float = 0.05) -> float:
    """The least distance between two polylines, sampled every step_m along a [m]."""
    return min(polyline_point_m(b, p) for p in sample(a, step_m))


def sample(line: list, step_m: float) -> list:
    """Points along a polyline, step_m apart and its ends."""
    out = [tuple(line[0])]
    for a, b in zip(line, line[1:]):
        n = max(1, int(math.dist(a, b) / step_m))
        out += [(a[0] + (b[0] - a[0]) * i / n, a[1] + (b[1] - a[1]) * i / n) for i in range(1, n + 1)]
    return out


def ahead(path: list, length_m: float) -> list:
    """The first length_m of a path."""
    if not path:
        return []
    out = [tuple(path[0])]
    left = length_m
    for a, b in zip(path, path[1:]):
        d = math.dist(a, b)
        if d >= left:
            t = left / d if d > 0 else 0.0
            out.append((a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t))
            return out
        out.append(tuple(b))
        left -= d
    return out


class PlanningMap:
    """A learned map as one rover's planner sees it: the shared map, with other rovers' bodies
    drawn in (what `plan_leg` reads of a LearnedMap: its grids, its known grid and echoes)."""

    def __init__(self, learned, disks: list[tuple[float, float]], extra_m: float):
        self._map = learned
        self._disks = np.asarray(disks, dtype=np.float64).reshape(-1, 2)
        self._extra_m = extra_m
        self.known_grid = learned.known_grid
        self.echoes = learned.echoes

    def _with_rovers(self, grid):
        if grid is None or not len(self._disks):
            return grid
        g = grid.copy()
        g.add_disks(self._disks, self._extra_m)
        return g

    @property
    def grid(self):
        return self._with_rovers(self._map.grid)

    def lenient_grid(self):
        return self._with_rovers(self._map.lenient_grid() or self._map.grid)

    def open_grids(self):
        return [self._with_rovers(g) for g in self._map.open_grids()]

    def point(self, e):
        return self._map.point(e)


class Traffic:
    """The fleet's traffic rules over its missions (see the module's doc)."""

    #: The turn-care trial's two rules (fleet/host.py; off by default): a rover that gave way
    #: waits for the rover it gave way to to pass (`GAVE_WAY_WAIT_S`), and no spot aside on the
    #: berth or the site of a rover with trips to do while there is another.
    give_way_wait: bool = False
    berth_rule: bool = False

    def __init__(self, missions: list, on_event=None):
        self.missions = missions
        self.on_event = on_event or (lambda t, text: None)
        self._clear_since: dict[int, float] = {}
        self._tried_at: dict[int, float] = {}  # when a held rover last tried a way round
        self._ring_tried_at: dict[int, float] = {}  # when a held rover last looked for a way aside
        self._gave_way: dict[int, tuple[int, float]] = {}  # giver: (the rover it gave way to, when)
        # Where each rover has been (the camera's fixes, TRACK_STEP_M apart): free ground to back
        # along when it must give way in a passage.
        self.tracks: list[list[tuple[float, float]]] = [[] for _ in missions]
        self.holds_by_rover = [0] * len(missions)
        self.give_ways = 0
        self.make_ways = 0  # parked rovers sent aside from home for another

    # ---------------------------------------------------------------- what each sees

    def position(self, k: int) -> tuple[float, float]:
        return self.missions[k].rover_xy()

    def standing(self, k: int) -> bool:
        m = self.missions[k]
        return not m.moving_leg

    def planning_map(self, k: int, also_moving: bool = False) -> PlanningMap:
        """Rover k's planner's map: the shared map with the other rovers drawn in: the standing ones'
        bodies, and the moving ones' paths (their lanes: where two rovers can keep apart, they do);
        with `also_moving`, the moving ones' bodies too (a held rover's plan round what holds it)."""
        disks = []
        for j, m in enumerate(self.missions):
            if j == k:
                continue
            disks.append(self.position(j))
            if not self.standing(j) and not also_moving:
                disks += sample(m.rest_of_leg(), LANE_STEP_M)[1:]
        shared = self.missions[k].map
        return PlanningMap(shared, disks, PLAN_CLEAR_M - shared.grid.config.inflation_m)

    def echo_is_rover(self, k: int, reading) -> bool:
        """Whether rover k's echo lies on another rover's body."""
        m = self.missions[k]
        p = m.map.point(Echo(reading.x_m, reading.y_m, reading.heading_deg, reading.bearing_deg, reading.range_m))
        return any(math.dist(p, self.position(j)) < ECHO_ON_ROVER_M for j in range(len(self.missions)) if j != k)

    # ---------------------------------------------------------------- the rules

    def _stretch(self, k: int) -> list:
        m = self.missions[k]
        rest = m.rest_of_leg()
        return ahead(rest, AHEAD_M) if rest else [self.position(k)]

    def blockers(self, k: int, stretch: list | None = None) -> list[int]:
        """The rovers in the way of rover k's stretch ahead (its own, or `stretch`): a rover the
        stretch would bring nearer than CLEAR_M (two rovers already that near, side by side at
        their starts, may move apart), or the stretch of a rover before k in the order."""
        stretch = stretch if stretch is not None else self._stretch(k)
        here = self.position(k)
        points = sample(stretch, 0.03)[1:] if len(stretch) > 1 else []
        out = []
        for j in range(len(self.missions)):
            if j == k:
                continue
            there = self.position(j)
            now_m = math.dist(here, there)
            if points and min(math.dist(p, there) for p in points) < min(CLEAR_M, now_m - 0.005):
                out.append(j)
            elif j < k and self.missions[j].moving_leg and points:
                theirs = self._stretch(j)
                if len(theirs) > 1 and polylines_m(points, theirs) < CLEAR_M:
                    out.append(j)
        return out

    def _follow(self) -> None:
        for k, track in enumerate(self.tracks):
            p = self.position(k)
            if not track or math.dist(track[-1], p) >= TRACK_STEP_M:
                track.append(p)
                del track[:-TRACK_KEEP]

    def tick(self, now_s: float) -> None:
        """Hold whoever must wait, let go whoever may go (one a tick)."""
        self._follow()
        missions = self.missions
        for k, m in enumerate(missions):
            if m.moving_leg and m.phase.value == "run" and m.path:
                who = self.blockers(k)
                if who:
                    self.holds_by_rover[k] += 1
                    m.hold(now_s, f"rover {who[0] + 1} is in the way (at {_xy(self.position(who[0]))})")
                    self._clear_since.pop(k, None)
        for k, m in enumerate(missions):
            if not m.held or m.done or m.parked_at_rest:  # parked at home: it waits for the fleet
                continue
            if self._try_let_go(k, now_s):
                return

    def _try_let_go(self, k: int, now_s: float) -> bool:
        m = self.missions[k]
        if m.parked and self._wanted_home(k):
            return False  # sent aside from home: back only once no rover's way passes its berth
        if m.settling(now_s):
            return False  # stopped as it backed out of a refused turn: planned once it has stopped
        if self._waits_for_passing(k, now_s):
            return False
        who = self.blockers(k)
        if not who:
            since = self._clear_since.setdefault(k, now_s)
            if now_s - since >= CLEAR_FOR_S:
                self._clear_since.pop(k, None)
                # Planned afresh from where it stands (it may have stopped off its line, or backed
                # out): the straight line from there to its next waypoint was never checked.
                m.let_go(now_s, None)
                return True
            return False
        self._clear_since.pop(k, None)
        waited = m.held_for_s(now_s)
        # A way round only what stands still (held, or parked at its base or site): a rover on the
        # move is waited for, it will be gone.
        standing = all(self.standing(j) for j in who)
        if standing and waited >= REPLAN_AFTER_S and now_s - self._tried_at.get(k, -math.inf) >= RETRY_S:
            self._tried_at[k] = now_s
            path = self._plan_round(k)
            if path is not None and not self.blockers(k, ahead(path, AHEAD_M)):
                self.on_event(now_s, f"rover {k + 1}: planned round rover {who[0] + 1}")
                m.let_go(now_s, path)
                return True
            if path is None and self._make_way(k, who, now_s):
                return True
        if waited >= GIVE_WAY_AFTER_S and now_s - self._ring_tried_at.get(k, -math.inf) >= RETRY_S:
            self._ring_tried_at[k] = now_s
            cycle = self._cycle(k)
            if cycle and k == max(cycle):
                # cycle[i] is held by cycle[i + 1] and holds cycle[i - 1] (k holds the last): the
                # latest in the order that has a clear way off the path of the rover it holds goes.
                for i in sorted(range(len(cycle)), key=lambda i: -cycle[i]):
                    g, j = cycle[i], cycle[i - 1]
                    if self.missions[g].settling(now_s):
                        continue  # still backing out of a refused turn: not sent anywhere yet
                    way = self._way_aside(g, j)
                    if way is not None:
                        self.give_ways += 1
                        if self.give_way_wait:
                            self._gave_way[g] = (j, now_s)
                        self.on_event(now_s, f"rover {g + 1} gives way to rover {j + 1}: back to {_xy(way[-1])}")
                        self.missions[g].let_go(now_s, way, aside=True)
                        return True
        return False

    def _waits_for_passing(self, k: int, now_s: float) -> bool:
        """Whether rover k, which gave way, still waits for the rover it gave way to to pass (see
        GAVE_WAY_WAIT_S): that rover is on the move and its way ahead still comes near k's own
        stretch ahead. While the rover it gave way to is held (for k, or any other) k is not kept
        waiting: the rules that hold it decide (rover 3, held on its way aside by a refused turn,
        waited for rover 1, which waited for rover 3: seed 2 of the seen-ground trial); the wait
        holds again once that rover moves on."""
        if k not in self._gave_way:
            return False
        j, since = self._gave_way[k]
        other = self.missions[j]
        theirs = other.rest_of_leg() if not (other.done or other.parked) else []
        if now_s - since >= GAVE_WAY_WAIT_S or len(theirs) < 2 or polylines_m(self._stretch(k), theirs) >= CLEAR_M:
            del self._gave_way[k]  # it has passed (or is home, or done), or long enough
            return False
        return other.moving_leg  # held a moment (for k, or any other): the rules that hold it decide

    def _way_aside(self, k: int, j: int):
        """Rover k's way off rover j's path: back along its own track, else a step aside, else a
        planned way to a spot off it (`_aside_spot`); one that passes no rover (backing along a track another rover now stands on, rover 3 of arena 6
        gave way every 4 s and was held at once, for good)."""
        for way in (self._back_away(k, j), self._side_step(k, j)):
            if way is not None and not self.blockers(k, way):
                return way
        return self._aside_spot(k, j)  # a planned way to a spot off j's way

    def _cycle(self, k: int) -> list[int] | None:
        """The held rovers that hold each other round to rover k (k, the rover in its way, the rover
        in that one's way, ...), two or more; None when the chain from k does not come back to it."""
        chain = [k]
        while True:
            who = self.blockers(chain[-1]) if self.missions[chain[-1]].held else []
            if not who:
                return None
            if who[0] == k:
                return chain
            if who[0] in chain:
                return None  # a cycle that k is not in (it waits behind one)
            chain.append(who[0])

    def _make_way(self, k: int, who: list[int], now_s: float) -> bool:
        """No way round for rover k: a rover in its way that is parked (its trips done), at home or
        waiting at a spot aside it was sent to before, is sent aside, off k's way, to wait there
        until k has gone by (True: one was). (Rover 3, sent aside from its berth for rover 1 to a
        spot 0.16 m from rover 2's berth, waited there for rover 2's way home to clear its own
        berth, and held rover 2, with no way round it to its berth, for good.)"""
        for j in who:
            other = self.missions[j]
            if not other.parked_waiting:
                continue
            spot = self._aside_spot(j, k)
            if spot is not None:
                self.make_ways += 1
                self.on_event(now_s, f"rover {j + 1} makes way for rover {k + 1}: aside to {_xy(spot[-1])}")
                other.let_go(now_s, spot, aside=True)
                return True
        return False

    def _wanted_home(self, k: int) -> bool:
        """Whether another rover's way (still to drive, or held) passes rover k's berth."""
        home = self.missions[k].current_leg.goal
        for j, other in enumerate(self.missions):
            if j == k or other.done or other.parked:
                continue
            rest = other.rest_of_leg()
            if len(rest) > 1 and polyline_point_m(rest, home) < CLEAR_M:
                return True
        return False

    def _plan_round(self, k: int, goal: tuple[float, float] | None = None):
        """Rover k's path to its leg's goal (or `goal`) round every other rover (None: none)."""
        m = self.missions[k]
        pm = self.planning_map(k, also_moving=True)
        saved = m.planning_map
        m.planning_map = lambda: pm
        try:
            return m.plan_from(m.rover_xy(), goal or m.current_leg.goal, verdict=False, round_rovers=True)
        finally:
            m.planning_map = saved

    def _aside_spot(self, j: int, k: int):
        """A path for rover j (parked, or giving way) to a spot off rover k's way (its path as if j were not there)
        and clear of every other rover, the nearest of those tried that j can reach (None: none); off the
        berths and sites of the rovers with trips to do where there is such a spot, else on one."""
        best = self._aside_spot_from(j, k, off_ends=True) if self.berth_rule else None
        return best if best is not None else self._aside_spot_from(j, k, off_ends=False)

    def _aside_spot_from(self, j: int, k: int, off_ends: bool):
        here = self.position(j)
        theirs = self.missions[k].rest_of_leg() or [self.position(k)]
        others = [self.position(i) for i in range(len(self.missions)) if i != j]
        # Nor on the berth or the site of a rover with trips to do: rover 3, sent aside from its
        # berth onto rover 1's to let rover 2 by, waited there for rover 2 to be home, and held
        # rover 1, on its way home, for good (seeds 1 and 2 of the seen-ground trial).
        ends = [
            q
            for i, m in enumerate(self.missions)
            if off_ends and i != j and not m.done
            for q in (m.start_xy, m.target_xy)
            if q is not None
        ]
        grid = self.planning_map(j, also_moving=True).grid
        tried, best = 0, None
        for r in ASIDE_RINGS_M:
            if best is not None and path_length_m(best) <= r:
                break  # no spot further out has a shorter way
            for a in range(0, 360, 360 // ASIDE_DIRECTIONS):
                p = (here[0] + r * math.sin(math.radians(a)), here[1] + r * math.cos(math.radians(a)))
                if not grid.contains(*p) or not grid.is_free(*p):
                    continue
                if polyline_point_m(theirs, p) < CLEAR_M + 0.03 or any(
                    math.dist(p, q) < PLAN_CLEAR_M + 0.03 for q in others + ends
                ):
                    continue
                if tried >= ASIDE_MAX_PLANS:
                    break
                tried += 1
                path = self._plan_round(j, p)
                if path is None or self.blockers(j, path):  # (the planner's fallbacks may cut corners)
                    continue
                if path_length_m(path) <= ASIDE_DETOUR * r and (
                    best is None or path_length_m(path) < path_length_m(best)
                ):
                    best = path
        return best  # the shortest way found: the less driving among the others, the better

    def _back_away(self, k: int, j: int):
        """Rover k's way back along its own track (ground it has just driven) to the first point
        clear of rover j's path and of every other rover (None: none in the track it keeps)."""
        here = self.position(k)
        theirs = self.missions[j].rest_of_leg() or [self.position(j)]
        others = [self.position(i) for i in range(len(self.missions)) if i != k]
        way = [here]
        for p in reversed(self.tracks[k][:-1]):
            if math.dist(way[-1], p) >= 0.10:
                way.append(p)
            if polyline_point_m(theirs, p) >= CLEAR_M + 0.05 and all(math.dist(p, q) >= CLEAR_M for q in others):
                if way[-1] != p:
                    way.append(p)
                return way if len(way) >= 2 else None
        return None

    def _side_step(self, k: int, j: int):
        """A short path for rover k off rover j's way: to the free spot nearest k, SIDE_STEP_M or
        so away, that leaves j's path clear (None: none)."""
        here = self.position(k)
        theirs = self.missions[j].rest_of_leg() or [self.position(j)]
        grid = self.planning_map(k, also_moving=True).grid
        best = None
        for r in (SIDE_STEP_M, SIDE_STEP_M * 1.5, SIDE_STEP_M * 2):
            for a in range(0, 360, 30):
                p = (here[0] + r * math.sin(math.radians(a)), here[1] + r * math.cos(math.radians(a)))
                if not grid.contains(*p) or not grid.is_free(*p):
                    continue
                if polyline_point_m(theirs, p) < CLEAR_M:
                    continue
                if not grid.segment_clear(here, p):
                    continue
                best = p
                break
            if best is not None:
                break
        if best is None:
            return None
        return [here, best]


def _xy(p) -> str:
    return f"({p[0]:.2f}, {p[1]:.2f}) m"
