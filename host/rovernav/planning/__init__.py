"""Path planning on the arena's occupancy grid.

    grid = OccupancyGrid.from_scenario(scenario, PlannerConfig())   # known obstacles, inflated
    result = plan(grid, scenario.start.xy, scenario.target.xy)     # A*, simplified waypoints [m]
    grid.add_sonar_echo(x, y, heading_deg, bearing_deg, range_m, path=result.waypoints)

A* runs the seed's 16-direction motion model and is optimal on its grid; the potential
field is the seed's comparison planner (Table 4.2). Every failure is a NoPathError.
"""
from .config import PlannerConfig
from .errors import GoalBlocked, LocalMinimum, NoPathError, OutsideArena, StartBlocked, Unreachable
from .grid import OccupancyGrid, SonarUpdate
from .planner import PLANNERS, PlanResult, plan, warm_up

__all__ = [
    "PLANNERS", "GoalBlocked", "LocalMinimum", "NoPathError", "OccupancyGrid", "OutsideArena",
    "PlanResult", "PlannerConfig", "SonarUpdate", "StartBlocked", "Unreachable", "plan", "warm_up",
]
