"""What the mission and its strategies know of each other: two protocols, and nothing else.

`Mission` (core.py) implements `MissionView`, the little a strategy may read and ask of the
mission; a strategy (strategies.py) implements `Strategy`, what the mission asks of it when a
leg starts, ends or meets a changed map. Both modules import this one; neither imports the other
for its types (core.py imports strategies.py only for the default strategy).
"""

from __future__ import annotations

from typing import Protocol

from ..link import messages_gen as mg
from ..planning import OccupancyGrid
from .legs import Leg

Path = list[tuple[float, float]]


class MissionView(Protocol):
    """The mission as a strategy sees it."""

    planner: str  # the planner's name (rovernav.planning.plan's `planner`)

    @property
    def grid(self) -> OccupancyGrid:
        """The planner's grid: the known obstacles and what the sonar found, inflated."""

    @property
    def current_leg(self) -> Leg:
        """The leg being driven (its goal, its deadline, what happened on it)."""

    @property
    def arrival_radius_m(self) -> float:
        """The rover's arrival radius, as the mission configured it [m]."""

    def steering_goal(self) -> tuple[float, float]:
        """Where the rover's path must lead: its leg's goal, or a fleet rover's spot out of another's way."""

    def aside_blocked(self) -> None:
        """A fleet rover's way to its spot aside is blocked: it waits where it is."""

    def rover_xy(self) -> tuple[float, float]:
        """Where the rover is: the camera's last fix if recent, else its own estimate."""

    def remaining_path(self) -> Path:
        """From where the rover is through the waypoints it has still to reach."""

    def plan_from(self, start: tuple[float, float], goal: tuple[float, float], verdict: bool = True) -> Path | None:
        """The mission's path from `start` to `goal` (its fallbacks and turn checks); None when there
        is none, the mission then failed with the no-path verdict unless `verdict` is False."""

    def load_path(self, path: Path) -> None:
        """Send `path` to the rover under a new id; START follows once it has it whole."""

    def replanned(self, path: Path, what: str, why: str = "the sonar found the path blocked") -> None:
        """Say that the strategy replanned the current leg (`what`: the new path in words), and give
        the leg time for it."""


class Strategy(Protocol):
    """How a leg is driven: what the mission asks of a strategy."""

    name: str
    note: str  # said when a leg starts

    def rover_params(self) -> list[tuple[mg.Param, int]]:
        """CONFIG parameters the strategy needs, sent before the mission's own."""

    def leg_path(self, m: MissionView, start: tuple[float, float], goal: tuple[float, float]) -> Path | None:
        """The path of a new leg (None: the mission has failed, with the reason)."""

    def start_leg(self, m: MissionView, path: Path) -> None:
        """Hand a new leg to the rover."""

    def on_arrived(self, m: MissionView) -> bool:
        """The rover arrived at the end of the path it was given: is the leg done?"""

    def map_changed(self, m: MissionView) -> None:
        """The map changed (after a sweep): replan if the rest of the leg is blocked."""

    def backed_out(self, m: MissionView) -> None:
        """The rover backed out to make room for a turn and heads for its next waypoint from there."""
