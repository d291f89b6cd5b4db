"""A generated arena made a fleet's shuttle (issue 30): more starts round its start (the base) and
more sites round its target, so that N rovers can each shuttle between a start and a site.

    sc = fleet_scenario(load_scenario("out/arenas/arena-0003-divider.toml"), rovers=3)
    sc.starts, sc.sites        # 3 of each (or FleetPlacementError: no room for them)

A start is a spot the planner's grid (every obstacle known) keeps free (its margin, 0.17 m, is past
the body's half-diagonal: the body touches nothing there at any heading), and every other start is `SPACING_M` away;
the same for sites round the target. Each rover's start and site are joined by a path with every
obstacle known (the arena is solvable for every rover, not for rover 1 alone). Spots are tried in
a row through the base, across the way to the target, nearest first on alternate sides, so that
each berth is reached from in front without passing another (rings round the base let parked
rovers wall one in).
"""

from __future__ import annotations

import dataclasses
import math

from ..errors import InputError
from ..planning import NoPathError, OccupancyGrid, PlannerConfig, plan
from ..scenario import Pose, Scenario, Target

#: Neighbouring starts (or sites) this far apart: a body's diagonal (0.26 m), the traffic rules'
#: margin, and room for a rover parked a little off its berth (its arrival radius) [m].
SPACING_M = 0.40
#: The row's turns from straight across the way, tried in turn [deg].
ROW_TURNS_DEG = (0, 20, -20, 40, -40, 60, -60)


class FleetPlacementError(InputError):
    """No room for the fleet's starts or sites in this arena."""


def _spots(centre, towards, count: int, grid: OccupancyGrid, taken=()):
    """`count` free spots in a row through `centre`, across the way to `towards`, SPACING_M apart,
    nearest first and on alternate sides: each is reached from the way in front without passing
    another's (rings round the base let parked rovers wall one in)."""
    way = math.atan2(towards[1] - centre[1], towards[0] - centre[0])
    for turn_deg in ROW_TURNS_DEG:  # the row straight across first, then turned a little
        a = way + math.pi / 2 + math.radians(turn_deg)
        across = (math.cos(a), math.sin(a))
        chosen = [tuple(centre)] + list(taken)
        out = []
        for i in range(1, 4 * count + 1):
            if len(out) == count:
                return out
            step = (i + 1) // 2 * SPACING_M * (1 if i % 2 else -1)
            p = (centre[0] + across[0] * step, centre[1] + across[1] * step)
            if not grid.contains(*p) or not grid.is_free(*p):
                continue
            if any(math.dist(p, q) < SPACING_M - 1e-9 for q in chosen):
                continue
            chosen.append(p)
            out.append(p)
        if len(out) == count:
            return out
    return None


def fleet_scenario(scenario: Scenario, rovers: int, config: PlannerConfig | None = None) -> Scenario:
    """The scenario with starts and sites for `rovers` (its own first; see the module's doc)."""
    if rovers <= len(scenario.starts) and rovers <= len(scenario.sites):
        return scenario
    grid = OccupancyGrid.from_scenario(scenario, config or PlannerConfig(), all_obstacles=True)
    h = scenario.start.heading_deg
    more_starts = list(scenario.more_starts)
    need = rovers - len(scenario.starts)
    if need > 0:
        spots = _spots(scenario.start.xy, scenario.target.xy, need, grid, [p.xy for p in more_starts])
        if spots is None:
            raise FleetPlacementError(f"{scenario.name}: no room for {rovers} starts round the base")
        more_starts += [Pose(round(x, 3), round(y, 3), h) for x, y in spots]
    more_sites = list(scenario.more_sites)
    need = rovers - len(scenario.sites)
    if need > 0:
        spots = _spots(scenario.target.xy, scenario.start.xy, need, grid, [p.xy for p in more_sites])
        if spots is None:
            raise FleetPlacementError(f"{scenario.name}: no room for {rovers} sites round the target")
        more_sites += [Target(round(x, 3), round(y, 3)) for x, y in spots]
    out = dataclasses.replace(scenario, more_starts=tuple(more_starts), more_sites=tuple(more_sites))
    for k, (a, b) in enumerate(out.fleet_legs(rovers)):
        try:
            plan(grid, a, b)
        except NoPathError as exc:
            raise FleetPlacementError(
                f"{scenario.name}: rover {k + 1} has no way from its start to its site: {exc}"
            ) from None
    return out
