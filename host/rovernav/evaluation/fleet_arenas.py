"""A generated arena made a fleet's shuttle (issue 30): more starts round its start (the base) and
more sites round its target, so that N rovers can each shuttle between a start and a site.

    sc = fleet_scenario(load_scenario("out/arenas/arena-0003-divider.toml"), rovers=3)
    sc.starts, sc.sites        # 3 of each (or FleetPlacementError: no room for them)

A start is a spot the planner's grid (every obstacle known) keeps free (its margin, 0.17 m, is past
the body's half-diagonal: the body touches nothing there at any heading), and every other start is `SPACING_M` away;
the same for sites round the target. Each rover's start and site are joined by a path with every
obstacle known (the arena is solvable for every rover, not for rover 1 alone), and by one that
passes the other rovers parked at their starts, and one past them at their sites (a berth reached
only past another's is a pocket: with its neighbour home, a rover could neither leave nor come
home; a site in another's way shuts it while that rover is there). Spots are tried in a row
through the base, across the way to the target, nearest first on alternate sides, so that each
berth is reached from in front without passing another (rings round the base let parked rovers
wall one in); rows turned from straight across, on one side only, then wider apart, and the sites'
rows, in turn, until one passes (at most MAX_LAYOUTS pairs).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import InputError
from ..planning import NoPathError, OccupancyGrid, PlannerConfig, plan
from ..scenario import Pose, Scenario, Target

#: Neighbouring starts (or sites) this far apart: a body's diagonal (0.26 m), the traffic rules'
#: margin, and room for a rover parked a little off its berth (its arrival radius) [m].
SPACING_M = 0.40
#: The row's turns from straight across the way, tried in turn [deg].
ROW_TURNS_DEG = (0, 20, -20, 40, -40, 60, -60)
KIND_NONE = (SPACING_M, (1, -1))  # the scenario names them all already
#: Rows tried after those SPACING_M apart [m].
WIDE_SPACING_M = 0.55
#: At most this many pairs of a row of starts and a row of sites are checked (each plans 3 ways a rover).
MAX_LAYOUTS = 300


class FleetPlacementError(InputError):
    """No room for the fleet's starts or sites in this arena."""


def _rows(centre, towards, count: int, grid: OccupancyGrid, taken=()):
    """Rows of `count` free spots through `centre`, across the way to `towards`, nearest first
    (each is reached from the way in front without passing another's: rings round the base let
    parked rovers wall one in): SPACING_M apart on alternate sides, straight across first, then
    turned by each of ROW_TURNS_DEG in turn; then the same on one side only, then all of it
    WIDE_SPACING_M apart (a neighbour at SPACING_M on each side may hem in the rover between)."""
    way = math.atan2(towards[1] - centre[1], towards[0] - centre[0])
    for spacing in (SPACING_M, WIDE_SPACING_M):
        for sides in ((1, -1), (1,), (-1,)):
            for turn_deg in ROW_TURNS_DEG:
                a = way + math.pi / 2 + math.radians(turn_deg)
                across = (math.cos(a), math.sin(a))
                chosen = [tuple(centre)] + list(taken)
                out = []
                for i in range(4 * count):
                    if len(out) == count:
                        break
                    step = (i // len(sides) + 1) * spacing * sides[i % len(sides)]
                    p = (centre[0] + across[0] * step, centre[1] + across[1] * step)
                    if not grid.contains(*p) or not grid.is_free(*p):
                        continue
                    if any(math.dist(p, q) < SPACING_M - 1e-9 for q in chosen):
                        continue
                    chosen.append(p)
                    out.append(p)
                if len(out) == count:
                    yield (spacing, sides), out


def _ways(out: Scenario, rovers: int, grid: OccupancyGrid) -> str | None:
    """Why a rover could not go from its start to its site and back, every obstacle known, with
    every other rover parked at its own start, or at its own site (None: each can): a berth (or a
    site) reached only past another's is a pocket that the rover standing there shuts."""
    from ..fleet.traffic import PLAN_CLEAR_M

    legs = out.fleet_legs(rovers)
    for k, (a, b) in enumerate(legs):
        try:
            plan(grid, a, b)
        except NoPathError as exc:
            return f"rover {k + 1} has no way from its start to its site: {exc}"
        for end, where in ((0, "parked at their starts"), (1, "at their sites")):
            others = np.asarray([leg[end] for j, leg in enumerate(legs) if j != k], dtype=np.float64).reshape(-1, 2)
            g = grid.copy()
            g.add_disks(others, PLAN_CLEAR_M - grid.config.inflation_m)
            try:
                plan(g, a, b)
            except NoPathError as exc:
                return f"rover {k + 1} has no way from its start to its site with the others {where}: {exc}"
    return None


def _facing(a, b) -> float:
    """The heading from a towards b [deg, 0 = +y, clockwise, as a scenario's], to a tenth."""
    return round(math.degrees(math.atan2(b[0] - a[0], b[1] - a[1])) % 360.0, 1)


def fleet_scenario(scenario: Scenario, rovers: int, config: PlannerConfig | None = None) -> Scenario:
    """The scenario with starts and sites for `rovers` (its own first; see the module's doc)."""
    if rovers <= len(scenario.starts) and rovers <= len(scenario.sites):
        return scenario
    grid = OccupancyGrid.from_scenario(scenario, config or PlannerConfig(), all_obstacles=True)
    # Each added rover stands facing the target: its first turn is small (a rover that must turn
    # hard on its berth by a wall may be refused the turn and back out blind, into the wall: arena
    # 45, rover 2, 28.9 s, facing the start's 45 deg with the wall 0.19 m behind it).
    tx, ty = scenario.target.xy
    start_rows = [(KIND_NONE, [])]
    need = rovers - len(scenario.starts)
    if need > 0:
        start_rows = list(
            _rows(scenario.start.xy, scenario.target.xy, need, grid, [p.xy for p in scenario.more_starts])
        )
        if not start_rows:
            raise FleetPlacementError(f"{scenario.name}: no room for {rovers} starts round the base")
    site_rows = [(KIND_NONE, [])]
    need = rovers - len(scenario.sites)
    if need > 0:
        site_rows = list(_rows(scenario.target.xy, scenario.start.xy, need, grid, [p.xy for p in scenario.more_sites]))
        if not site_rows:
            raise FleetPlacementError(f"{scenario.name}: no room for {rovers} sites round the target")
    why = None
    # The rows of each kind (spacing, sides) in the order _rows gives them: a layout of two kinds
    # comes after every layout of kinds before both (the first kind's layouts are the old ones).
    kinds = [(SPACING_M, (1, -1)), (SPACING_M, (1,)), (SPACING_M, (-1,))]
    kinds += [(WIDE_SPACING_M, k) for _, k in kinds]
    layouts = sorted(
        ((a, b) for a in start_rows for b in site_rows),
        key=lambda ab: max(kinds.index(ab[0][0]), kinds.index(ab[1][0])),
    )[:MAX_LAYOUTS]
    for (_, starts), (_, sites) in layouts:
        out = dataclasses.replace(
            scenario,
            more_starts=tuple(scenario.more_starts)
            + tuple(Pose(round(x, 3), round(y, 3), _facing((x, y), (tx, ty))) for x, y in starts),
            more_sites=tuple(scenario.more_sites) + tuple(Target(round(x, 3), round(y, 3)) for x, y in sites),
        )
        why = _ways(out, rovers, grid)
        if why is None:
            return out
    raise FleetPlacementError(f"{scenario.name}: no base for {rovers} rovers: {why}")
