"""`rovernav plan SCENARIO`: plan a path on a scenario and print it (or JSON, or a picture).

    rovernav plan seed-small-obstacles                    A* on the known obstacles
    rovernav plan seed-large-obstacles --planner potential --all-obstacles --json
    rovernav plan seed-small-obstacles --planner theta     any-angle (Lazy Theta*)
    rovernav plan path/to/arena.toml --resolution 0.05 --plot path.png

Exit status 0 when a path is found, 1 when there is none (the reason on stderr), 2 for input
that cannot be used (a scenario, a flag, a grid too large to build).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from ..validate import MAX_GRID_CELLS, number, output_file


def add_plan_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    """Register the `plan` command on a parser's subparsers; its handler returns the exit status."""
    p = subparsers.add_parser(
        "plan",
        help="plan a path from a scenario's start to its target",
        description="Build the scenario's occupancy grid (obstacles inflated by the robot radius plus the "
        "sonar margin), plan from the start to the target, and print the simplified waypoints "
        "[m], the path's length and the time taken.",
        epilog="exit status: 0 a path was found; 1 there is none (the reason is printed); 2 the scenario, a "
        "flag or a grid too large to build cannot be used (a one-line error names it); 3 an internal "
        "error (rerun with -v for the traceback); 130 interrupted.",
    )
    p.add_argument(
        "scenario",
        metavar="SCENARIO",
        help="a shared scenario's name (e.g. seed-small-obstacles) or the path of a scenario file",
    )
    p.add_argument(
        "--planner",
        choices=("astar", "theta", "potential"),  # planner.PLANNERS (not imported here: --help stays quick)
        default="astar",
        help="astar: A* over the 16-direction grid (default); theta: Lazy Theta*, any-angle segments "
        "on the same grid, each checked to touch no inflated cell (shorter, fewer waypoints); "
        "potential: the seed's potential field",
    )
    p.add_argument(
        "--all-obstacles", action="store_true", help="plan around every obstacle, not only those marked known = true"
    )
    p.add_argument(
        "--json",
        action="store_true",
        help='print {"found", "waypoints", "length_m", "time_ms", "planner", "reason"} as JSON',
    )
    p.add_argument(
        "--resolution",
        type=number(0.001, 1.0),
        metavar="M",
        default=None,
        help=f"grid cell size in metres, 0.001 to 1 (default 0.03); the grid may have at most {MAX_GRID_CELLS:,} cells",
    )
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        default=None,
        type=output_file(".png"),
        help="also draw the grid, the obstacles (raw and inflated) and the path into a PNG",
    )
    p.set_defaults(func=run_plan)
    return p


def run_plan(args: argparse.Namespace) -> int:
    """The `plan` command's handler."""
    from ..scenario import ScenarioError, load_scenario
    from . import NoPathError, OccupancyGrid, PlannerConfig, plan
    from .errors import LocalMinimum
    from .planner import warm_up

    try:
        scenario = load_scenario(args.scenario)
        config = PlannerConfig() if args.resolution is None else PlannerConfig(resolution_m=args.resolution)
    except (ScenarioError, ValueError) as exc:
        print(f"rovernav plan: {exc}", file=sys.stderr)
        return 2

    warm_up()
    t0 = time.perf_counter()
    grid = OccupancyGrid.from_scenario(scenario, config, all_obstacles=args.all_obstacles)
    grid_ms = (time.perf_counter() - t0) * 1e3
    result, reason, partial = None, None, None
    t1 = time.perf_counter()
    try:
        result = plan(grid, scenario.start.xy, scenario.target.xy, planner=args.planner)
    except NoPathError as exc:
        reason = exc.reason
        partial = exc.partial if isinstance(exc, LocalMinimum) else None
    time_ms = result.time_s * 1e3 if result else (time.perf_counter() - t1) * 1e3

    if args.plot:
        from .potential import body_layer
        from .render import render, write_png

        ignored = [(o.x_m, o.y_m, o.w_m, o.h_m) for o in scenario.obstacles if not (args.all_obstacles or o.known)]
        image = render(
            grid,
            result.waypoints if result else None,
            result.cells if result else None,
            scenario.start.xy,
            scenario.target.xy,
            unknown_boxes=ignored,
            partial=partial,
            body=body_layer(grid) if args.planner == "potential" else None,
        )
        try:
            write_png(args.plot, image)
        except OSError as exc:
            print(f"rovernav plan: {exc}", file=sys.stderr)
            return 2

    if args.json:
        print(
            json.dumps(
                {
                    "found": result is not None,
                    "waypoints": [[round(x, 4), round(y, 4)] for x, y in result.waypoints] if result else [],
                    "length_m": round(result.length_m, 4) if result else None,
                    "time_ms": round(time_ms, 3),
                    "planner": args.planner,
                    "reason": reason,
                }
            )
        )
    elif result:
        name = {"astar": "A*", "theta": "Theta*"}.get(args.planner, "potential field")
        known = "all obstacles" if args.all_obstacles else f"{len(scenario.known_shapes)} known obstacles"
        print(
            f"{scenario.name}: {name} found a path of {result.length_m:.3f} m in {time_ms:.2f} ms "
            f"({grid.nx} × {grid.ny} cells of {grid.resolution_m} m built in {grid_ms:.2f} ms, {known}, "
            f"{result.expansions} expansions, {len(result.cells)} cells → {len(result.waypoints)} waypoints)"
        )
        for i, (x, y) in enumerate(result.waypoints):
            print(f"  {i:3d}  x {x:6.3f} m  y {y:6.3f} m")
    if result is None:
        print(f"rovernav plan: {scenario.name}: no path: {reason}", file=sys.stderr)
        return 1
    return 0
