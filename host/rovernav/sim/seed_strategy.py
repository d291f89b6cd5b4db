"""The seed's own behaviour, run in the same simulated world, as the baseline.

Pont (2019) kept the autonomy on the laptop: the host sent the rover a heading error and a
distance to the current grid waypoint on every frame, the rover stopped at each waypoint
(A*'s raw path, one cell of 0.03 m after another, no simplification), and it stopped for a
sonar sweep every 0.3 m that took about 9 s (500 ms + 500 ms per 15-degree step).

Here the same firmware runs (it is the only rover we have), driven the seed's way: the host
sends one waypoint at a time, the next raw grid cell beyond the arrival radius, and START; the
rover rotates, drives, stops on arrival, and waits for the next. Sweeps are slowed to the
seed's pace (sweep_step_ms = 750 gives 12 x 0.75 s = 9 s a sweep). The PID, the tolerance cone
and the arrival radius are the seed's in both strategies.
"""
from __future__ import annotations

import math

from ..link import messages_gen as mg
from ..mission import Mission, NoPathError, Phase, plan


def seed_rover_params() -> list[tuple[mg.Param, int]]:
    return [(mg.Param.SWEEP_STEP_MS, 750)]


class SeedMission(Mission):
    """Mission with the seed's strategy: every raw grid cell is a stop."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._cells: list[tuple[float, float]] = []
        self._next_cell = 0

    def _raw_path(self, start, goal) -> list[tuple[float, float]] | None:
        try:
            result = plan(self.grid, start, goal, planner=self.planner)
        except NoPathError:
            path = self._plan_from(start, goal)   # its fallbacks (nearest free cell) and failure report
            return path
        return [self.grid.cell_to_world(int(ix), int(iy)) for ix, iy in result.cells] + [goal]

    LEG_NOTE = " (seed strategy, every grid cell a waypoint)"

    def _leg_path(self, start, goal):
        return self._raw_path(start, goal)

    def _start_leg(self, path) -> None:
        self._cells, self._next_cell = path, 0
        self._send_next()

    def _send_next(self) -> None:
        here = self._rover_xy()
        radius = 0.036
        while self._next_cell < len(self._cells) - 1 and math.dist(here, self._cells[self._next_cell]) < radius:
            self._next_cell += 1
        target = self._cells[self._next_cell]
        self._start_sent = False
        self.phase = Phase.LOAD   # each waypoint is a mission of its own: path, then START
        self._send_path([here, target])

    def _on_event(self, m: mg.Event) -> None:
        if m.kind == mg.EventKind.ARRIVED and self.phase is Phase.RUN and self._cells:
            self.events.append((self._now, m))
            if self._next_cell >= len(self._cells) - 1:
                self._cells = []
                super()._on_event(m)   # the trip is done
                return
            self._next_cell += 1
            self._send_next()
            return
        super()._on_event(m)

    def _check_path(self) -> None:
        self._map_changed_at = None
        if not (self.host_replan and self._cells and self.legs):
            return
        rest = [self._rover_xy()] + self._cells[self._next_cell:]
        if not self.grid.path_blocked(rest):
            return
        cells = self._raw_path(self._rover_xy(), self.legs[-1].goal)
        if cells is None:
            return
        self.replans += 1
        self.legs[-1].replans += 1
        self.on_event(self._now, f"the sonar found the path blocked: replanned ({len(cells)} grid waypoints)")
        self._cells, self._next_cell = cells, 0
        self._send_next()
