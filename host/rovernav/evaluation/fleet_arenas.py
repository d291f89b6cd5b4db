"""A generated arena made a fleet's shuttle (issue 30): more starts round its start (the base) and
more sites round its target, so that N rovers can each shuttle between a start and a site.

    sc = fleet_scenario(load_scenario("out/arenas/arena-0003-divider.toml"), rovers=3)
    sc.starts, sc.sites        # 3 of each (or FleetPlacementError: no room for them)

A start is a spot the planner's grid (every obstacle known) keeps free (its margin, 0.17 m, is past
the body's half-diagonal: the body touches nothing there at any heading), and every other start is `START_SPACING_M` + `GAP_M` away;
the same for sites round the target. Each rover's start and site are joined by a path with every
obstacle known (the arena is solvable for every rover, not for rover 1 alone). Spots are tried on
rings round the base, nearest first, so that the base stays a base; the first that fit are taken.
"""

from __future__ import annotations

import dataclasses
import math

from ..errors import InputError
from ..planning import NoPathError, OccupancyGrid, PlannerConfig, plan
from ..scenario import START_SPACING_M, Pose, Scenario, Target

#: Room between two rovers' bodies at neighbouring starts (or sites) beyond a body's diagonal [m].
GAP_M = 0.06
#: The rings round the base tried, in turn [m].
RINGS_M = (0.32, 0.40, 0.50, 0.62, 0.75, 0.9)


class FleetPlacementError(InputError):
    """No room for the fleet's starts or sites in this arena."""


def _spots(centre, count: int, grid: OccupancyGrid, taken=()):
    spacing = START_SPACING_M + GAP_M
    chosen = [tuple(centre)] + list(taken)
    out = []
    for r in RINGS_M:
        n = max(8, int(2 * math.pi * r / 0.08))
        for i in range(n):
            if len(out) == count:
                return out
            a = 2 * math.pi * i / n
            p = (centre[0] + r * math.cos(a), centre[1] + r * math.sin(a))
            if not grid.contains(*p) or not grid.is_free(*p):
                continue
            if any(math.dist(p, q) < spacing for q in chosen):
                continue
            chosen.append(p)
            out.append(p)
    return out if len(out) == count else None


def fleet_scenario(scenario: Scenario, rovers: int, config: PlannerConfig | None = None) -> Scenario:
    """The scenario with starts and sites for `rovers` (its own first; see the module's doc)."""
    if rovers <= len(scenario.starts) and rovers <= len(scenario.sites):
        return scenario
    grid = OccupancyGrid.from_scenario(scenario, config or PlannerConfig(), all_obstacles=True)
    h = scenario.start.heading_deg
    more_starts = list(scenario.more_starts)
    need = rovers - len(scenario.starts)
    if need > 0:
        spots = _spots(scenario.start.xy, need, grid, [p.xy for p in more_starts])
        if spots is None:
            raise FleetPlacementError(f"{scenario.name}: no room for {rovers} starts round the base")
        more_starts += [Pose(round(x, 3), round(y, 3), h) for x, y in spots]
    more_sites = list(scenario.more_sites)
    need = rovers - len(scenario.sites)
    if need > 0:
        spots = _spots(scenario.target.xy, need, grid, [p.xy for p in more_sites])
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
