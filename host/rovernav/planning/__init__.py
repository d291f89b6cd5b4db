"""Path planning on the arena's occupancy grid.

    grid = OccupancyGrid.from_scenario(scenario, PlannerConfig())   # known obstacles, inflated
    result = plan(grid, scenario.start.xy, scenario.target.xy)     # A*, simplified waypoints [m]

A* runs the seed's 16-direction motion model and is optimal on its grid; Theta*
(planner="theta") plans any-angle paths on the same grid; the potential field is the seed's
comparison planner (Table 4.2). Every failure is a NoPathError.
"""

from .config import PlannerConfig
from .errors import GoalBlocked, LocalMinimum, NoPathError, OutsideArena, StartBlocked, Unreachable

# The grid and the planners compile with numba (about 0.2 s to import): loaded when first used,
# so that a command that only parses its flags (`rovernav plan --help`, a refused flag) is quick.
_LAZY = {
    "OccupancyGrid": ".grid",
    "PLANNERS": ".planner",
    "PlanResult": ".planner",
    "plan": ".planner",
    "warm_up": ".planner",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "PLANNERS",
    "GoalBlocked",
    "LocalMinimum",
    "NoPathError",
    "OccupancyGrid",
    "OutsideArena",
    "PlanResult",
    "PlannerConfig",
    "StartBlocked",
    "Unreachable",
    "plan",
    "warm_up",
]
