"""How a leg is driven: rovernav's strategy and the 2019 seed's, two strategies of one interface.

A strategy decides a leg's path, how it is handed to the rover, what an arrival means, and
what to do when the map changes. The mission (`rovernav.mission.Mission`) does the rest:
phases, deadlines, requests, the map. Both run the same firmware. A strategy sees the mission
only through `MissionView` and is a `Strategy` to it (both in interface.py).

- `RovernavStrategy`: A*'s path simplified to a few waypoints, sent whole; the rover follows it,
  sweeps every 0.3 m and detours on its own; the host replans when a sweep shows the rest of
  the path blocked.
- `SeedStrategy`: Pont (2019) kept the autonomy on the laptop: the rover stopped at every
  raw grid cell of A*'s path (0.03 m apart) and swept for about 9 s every 0.3 m
  (500 ms + 500 ms per 15-degree step). Here the host sends one cell at a time (the next
  beyond the arrival radius) and START; sweeps are slowed to the seed's pace
  (sweep_step_ms = 750 gives 12 x 0.75 s = 9 s a sweep).
"""

from __future__ import annotations

import math

from ..link import messages_gen as mg
from ..planning import NoPathError, plan
from ..planning.turns import body_clear
from .interface import MissionView, Path, Strategy


class RovernavStrategy:
    name = "rovernav"
    note = ""

    def rover_params(self) -> list[tuple[mg.Param, int]]:
        return []

    def leg_path(self, m: MissionView, start, goal):
        return m.plan_from(start, goal)

    def start_leg(self, m: MissionView, path):
        m.load_path(path)

    def on_arrived(self, m: MissionView):
        return True

    def map_changed(self, m: MissionView):
        remaining = m.remaining_path()
        if not remaining or not m.grid.path_blocked(remaining):
            return
        self._replan(m)

    def backed_out(self, m: MissionView):
        # The straight line from where it stopped backing out to its next waypoint cuts the
        # corner the path went round: replanned when the body's sides would not clear it (seed
        # 1's arena 189: a rover backed out from the end of a divider and drove on into it).
        # No way from there (it may stand inside a margin) is no verdict: the path it has stays.
        remaining = m.remaining_path()
        if len(remaining) >= 2 and not body_clear(m.grid, remaining[0], remaining[1]):
            self._replan(m, verdict=False, why="the line on from where the rover backed out scrapes")

    def _replan(self, m: MissionView, verdict=True, why="the sonar found the path blocked"):
        goal = m.steering_goal()
        aside = goal != m.current_leg.goal  # a fleet's rover on its way out of another's way
        new = m.plan_from(m.rover_xy(), goal, verdict and not aside)
        if new is None and aside:
            m.aside_blocked()  # no verdict on a spot aside: it waits where it is instead
        elif new is not None:
            m.replanned(new, f"{len(new)} waypoints", why)
            m.load_path(new)


class SeedStrategy:
    name = "seed"
    note = " (seed strategy, every grid cell a waypoint)"

    def __init__(self):
        self.cells: Path = []
        self.next_cell = 0

    def rover_params(self):
        # The seed's rover: 9-second sweeps, echoes within 0.4 m, no look before it first moves or
        # turns, no forward reflex.
        return [
            (mg.Param.SWEEP_STEP_MS, 750),
            (mg.Param.SONAR_REPORT_MM, 400),
            (mg.Param.SWEEP_AT_START, 0),
            (mg.Param.SWEEP_BEFORE_TURN_DEG, 0),
            (mg.Param.REFLEX_PING_MS, 0),
        ]

    def _raw_path(self, m: MissionView, start, goal):
        try:
            result = plan(m.grid, start, goal, planner=m.planner)
        except NoPathError:
            return m.plan_from(start, goal)  # its fallbacks (nearest free cell) and failure verdict
        return [m.grid.cell_to_world(int(ix), int(iy)) for ix, iy in result.cells] + [goal]

    def leg_path(self, m: MissionView, start, goal):
        return self._raw_path(m, start, goal)

    def start_leg(self, m: MissionView, path):
        self.cells, self.next_cell = path, 0
        self._send_next(m)

    def _send_next(self, m: MissionView):
        here = m.rover_xy()
        radius_m = m.arrival_radius_m
        while self.next_cell < len(self.cells) - 1 and math.dist(here, self.cells[self.next_cell]) < radius_m:
            self.next_cell += 1
        m.load_path([here, self.cells[self.next_cell]])  # each cell is a path of its own: path, then START

    def on_arrived(self, m: MissionView):
        if not self.cells or self.next_cell >= len(self.cells) - 1:
            self.cells = []
            return True
        self.next_cell += 1
        self._send_next(m)
        return False

    def backed_out(self, m: MissionView):
        pass  # the seed's rover goes one cell at a time: its next cell is a few centimetres on

    def map_changed(self, m: MissionView):
        if not self.cells:
            return
        rest = [m.rover_xy()] + self.cells[self.next_cell :]
        if not m.grid.path_blocked(rest):
            return
        cells = self._raw_path(m, m.rover_xy(), m.current_leg.goal)
        if cells is None:
            return
        m.replanned(cells, f"{len(cells)} grid waypoints")
        self.cells, self.next_cell = cells, 0
        self._send_next(m)


STRATEGIES = {"rovernav": RovernavStrategy, "seed": SeedStrategy}


def make_strategy(name: str) -> Strategy:
    try:
        return STRATEGIES[name]()
    except KeyError:
        raise ValueError(f"unknown strategy {name!r} (choose from {', '.join(STRATEGIES)})") from None
