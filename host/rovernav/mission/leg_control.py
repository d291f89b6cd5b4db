"""A mission's legs: the first path of each, the same leg again from where the rover is (after a
restart or when it is late), a leg's deadline, a strategy's replan, and the legs a restarted host
takes up.

`LegControl` is a part of `Mission` (core.py), kept apart by concern like `RoverFrames`: its
methods read and change the mission's own state, and call the mission's means of acting
(`_fail`, `_leg_done`, the strategy's `start_leg`, ...). It is not used on its own.
"""

from __future__ import annotations

import math

from .leg_plan import START_NEAR_M, plan_leg
from .legs import Leg, leg_goal, path_length_m
from .phases import Failure


class LegControl:
    """The mission's legs: started, resumed, watched and replanned (a base class of Mission)."""

    def _watch_leg(self, now_s: float) -> None:
        """The leg's deadline, and an arrival that only the rover's STATUS shows (its ARRIVED event
        was lost): the recovery is to re-plan from where the rover is and send the leg again."""
        if self.watch_blocked(now_s):
            return
        leg = self.current_leg
        if now_s <= leg.deadline_s:
            return
        if leg.recoveries >= self.deadlines.leg_recoveries:
            why = f"leg {leg.index + 1} not reached after {now_s - leg.started_s:.0f} s and {leg.recoveries} re-sends"
            if not self.give_up(now_s, why):
                self._fail(why, Failure.LEG_LATE)
            return
        leg.recoveries += 1
        self.on_event(
            now_s,
            f"leg {leg.index + 1} is late: re-planning from where the rover is "
            f"(recovery {leg.recoveries} of {self.deadlines.leg_recoveries})",
        )
        self._resume()

    def _next_leg(self) -> None:
        index = len(self.legs)
        goal = leg_goal(self.start_xy, self.target_xy, index)
        leg = Leg(index=index, goal=goal, started_s=self._now)
        self.legs.append(leg)
        here = self.rover_xy()
        if math.dist(here, goal) <= self.arrival_radius_m:
            # Already there: a leg that is done at once is done (the rover would not move).
            self.on_event(
                self._now,
                f"leg {index + 1}: the rover is already within "
                f"{self.arrival_radius_m * 1000:.0f} mm of ({goal[0]:.2f}, {goal[1]:.2f}) m",
            )
            self._leg_done()
            return
        path = self.strategy.leg_path(self, here, goal)
        if path is None:
            return
        leg.planned_length_m = path_length_m(path)
        leg.deadline_s = self._now + self.deadlines.leg_s(leg.planned_length_m)
        self.on_event(
            self._now,
            f"leg {index + 1}{self.strategy.note}: {len(path)} waypoints, "
            f"{leg.planned_length_m:.2f} m to ({goal[0]:.2f}, {goal[1]:.2f}) m",
        )
        self.strategy.start_leg(self, path)

    def _resume(self) -> None:
        """The current leg again, from where the rover is (after a rover restart or a late leg)."""
        leg = self.current_leg
        path = self.strategy.leg_path(self, self.rover_xy(), leg.goal)
        if path is None:
            return
        leg.deadline_s = self._now + self.deadlines.leg_s(path_length_m(path))
        self.strategy.start_leg(self, path)

    def replanned(
        self, path: list[tuple[float, float]], what: str, why: str = "the sonar found the path blocked"
    ) -> None:
        """A strategy replanned the current leg (after the map changed, or `why`)."""
        self.replans += 1
        leg = self.current_leg
        leg.replans += 1
        leg.deadline_s = max(leg.deadline_s, self._now + self.deadlines.leg_s(path_length_m(path)))
        self.on_event(self._now, f"{why}: replanned ({what}, {path_length_m(path):.2f} m)")

    def plan_from(
        self, start: tuple[float, float], goal: tuple[float, float], verdict: bool = True, round_rovers: bool = False
    ) -> list[tuple[float, float]] | None:
        """A* from `start` to `goal`, simplified (leg_plan.plan_leg: its fallbacks, its turns); None
        when there is none (the mission has then ended with the no-path verdict and the planner's
        reason, unless `verdict` is False: a check that may keep the path the rover has)."""
        # The turn at the start counts from the rover's heading when the path starts where it stands.
        heading = self.rover_heading_deg() if math.dist(start, self.rover_xy()) <= START_NEAR_M else None
        refused = self.current_leg.refused_twice() if self.legs else []
        # A fleet's rover in the turn-care trial is stopped as it begins to back out of a refused turn
        # (hold_on_refused): planned afresh from there, its first turn is checked against where it refused,
        # and a back-out against the line on from where it would end (leg_plan.plan_leg).
        refused_at = list(self.current_leg.turns_refused_at) if self.legs and self.hold_on_refused else None
        # What the rover's reflex met in this leg keeps its full margin (leg_plan.with_margin_round),
        # first round the other rovers, then through them (the traffic rules hold it until they
        # have moved); only when that leaves no way at all, the way as before (a verdict of no
        # path would end the mission). A way round the rovers in its way (round_rovers: the
        # traffic rules asking) keeps the margin: they will move.
        stopped_by = list(self.current_leg.stopped_by) if self.legs else []
        tries = [(self._planning_map(), stopped_by)]
        if self.planning_map is not None and not round_rovers:
            tries.append((self.map, stopped_by))  # no way round the fleet's other rovers: as if they were not there
        if stopped_by and not round_rovers:
            tries += [(learned, None) for learned, _ in tries]
        for learned, firm in tries:
            path, reason = plan_leg(
                learned,
                start,
                goal,
                planner=self.planner,
                heading=heading,
                refused=refused,
                say=lambda text: self.on_event(self._now, text),
                arrival_m=self.arrival_radius_m,
                refused_at=refused_at,
                stopped_by=firm,
            )
            if path is not None:
                break
        if path is None and verdict:
            self._fail(f"no path to ({goal[0]:.2f}, {goal[1]:.2f}) m: {reason}", Failure.NO_PATH)
        return path

    def remaining_path(self) -> list[tuple[float, float]]:
        """From where the rover is through the waypoints it has still to reach."""
        if not self.path:
            return []
        wp = self.last_status.waypoint_index if self.last_status else 0
        return [self.rover_xy()] + self.path[min(wp, len(self.path) - 1) :] + self.path_rest

    def restore_state(self) -> int:
        """A restarted host: take up the mission at the leg the last host had reached (from
        state_file; the rover's HELLO and STATUS then say the rest). Returns the legs done."""
        done = min(self.record.load(), self.legs_asked)
        for i in range(done):
            self.legs.append(
                Leg(
                    index=i,
                    goal=leg_goal(self.start_xy, self.target_xy, i),
                    started_s=self._now,
                    finished_s=self._now,
                    reached=True,
                )
            )
        return done
