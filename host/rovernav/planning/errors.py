"""Why a planner found no path: a small hierarchy under `NoPathError`.

NoPathError
 ├── OutsideArena     the start or the target is off the arena
 ├── StartBlocked     the start is inside an (inflated) obstacle or too close to the wall
 ├── GoalBlocked      the same for the target
 ├── Unreachable      both are free, but no route joins them
 └── LocalMinimum     the potential-field planner stopped where no neighbour is lower
"""

from __future__ import annotations

from ..errors import PlanningError


def fmt_xy(xy: tuple[float, float]) -> str:
    return f"({xy[0]:.2f}, {xy[1]:.2f}) m"


class NoPathError(PlanningError):
    """The planner found no path. `reason` is the one-line message."""

    @property
    def reason(self) -> str:
        return str(self)


class OutsideArena(NoPathError):
    """`which` ("start" or "target") lies outside the arena."""

    def __init__(self, which: str, xy: tuple[float, float], width_m: float, height_m: float):
        super().__init__(f"{which} {fmt_xy(xy)} is outside the {width_m:.2f} × {height_m:.2f} m arena")
        self.which = which
        self.xy = xy


class _Blocked(NoPathError):
    which = ""

    def __init__(self, xy: tuple[float, float], clearance_m: float, what: str = "robot radius + sonar margin"):
        super().__init__(
            f"{self.which} {fmt_xy(xy)} is blocked: it lies within {clearance_m:.2f} m "
            f"({what}) of an obstacle or the arena wall"
        )
        self.xy = xy


class StartBlocked(_Blocked):
    """The start cell is inside the inflated obstacles."""

    which = "start"


class GoalBlocked(_Blocked):
    """The target cell is inside the inflated obstacles."""

    which = "target"


class Unreachable(NoPathError):
    """Start and target are free, but obstacles separate them."""

    def __init__(self, start: tuple[float, float], goal: tuple[float, float]):
        super().__init__(f"no path from start {fmt_xy(start)} to target {fmt_xy(goal)}: obstacles enclose one of them")
        self.start = start
        self.goal = goal


class LocalMinimum(NoPathError):
    """The potential field has no lower neighbour at `xy`; `partial` is the descent so far [m]."""

    def __init__(self, xy: tuple[float, float], partial: list[tuple[float, float]]):
        super().__init__(f"trapped in a local minimum at {fmt_xy(xy)}")
        self.xy = xy
        self.partial = partial
