"""`rovernav pose` and `rovernav study`: the seed study's tasks from the command line.

    rovernav pose                                   P0 → P1 with the report's gains, 4 cm/s
    rovernav pose --from 0 0 0 --to 10 5 1.57 --gains 0.5 1.2 -0.4 --vmax 0.3 --json
    rovernav study --out study-out --seed 0         all three tasks, figures and summary.json

Metres, radians (θ from the x axis, counter-clockwise), seconds. Exit status: 0 done; 1 the
pose was not reached within the time limit; 2 bad arguments (unstable gains, bad vmax or dt)
or no path on the crater map.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time


def add_pose_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    """Register the `pose` command; its handler returns the exit status."""
    from .pose import CURIOSITY_VMAX_M_S, REPORT_P0, REPORT_P1, PoseGains

    g = PoseGains()
    p = subparsers.add_parser(
        "pose", help="drive to a pose with the moving-to-a-pose law (the seed study's navigation task)",
        description="Simulate the moving-to-a-pose law (v = K_rho rho, omega = K_alpha alpha + K_beta beta) "
                    "with Euler steps until the rover is within 0.1 m and 1e-3 rad of the goal pose; print "
                    "the time taken and the final state error. Exit 2 for unstable gains.")
    p.add_argument("--from", dest="start", nargs=3, type=float, metavar=("X", "Y", "THETA"), default=list(REPORT_P0),
                   help="start pose [m m rad] (default the report's P0)")
    p.add_argument("--to", dest="goal", nargs=3, type=float, metavar=("X", "Y", "THETA"), default=list(REPORT_P1),
                   help="goal pose [m m rad] (default the report's P1)")
    p.add_argument("--gains", nargs=3, type=float, metavar=("KR", "KA", "KB"),
                   default=[g.k_rho, g.k_alpha, g.k_beta], help="K_rho K_alpha K_beta (default the report's Table 1)")
    p.add_argument("--vmax", type=float, default=CURIOSITY_VMAX_M_S, metavar="M_S",
                   help="top speed [m/s] (default 0.04, Curiosity)")
    p.add_argument("--dt", type=float, default=1.0, metavar="S", help="Euler step [s] (default 1)")
    p.add_argument("--json", action="store_true", help="print {time_s, final_error, path_length_m, converged} as JSON")
    p.add_argument("--plot", metavar="FILE.png", default=None, help="draw trajectory, v, theta and omega into a PNG")
    p.set_defaults(func=run_pose)
    return p


def run_pose(args: argparse.Namespace) -> int:
    """The `pose` command's handler."""
    from .pose import PoseGains, plot_pose, simulate_pose

    try:
        gains = PoseGains(*args.gains)
        run = simulate_pose(args.start, args.goal, gains, vmax=args.vmax, dt=args.dt)
    except ValueError as exc:
        print(f"rovernav pose: {exc}", file=sys.stderr)
        return 2
    if args.plot:
        plot_pose(run, args.plot)
    err = run.final_error
    if args.json:
        print(json.dumps({"time_s": run.time_s, "final_error": err, "path_length_m": run.path_length_m,
                          "converged": run.converged, "strongly_stable": gains.strongly_stable}))
    else:
        print(f"time: {run.time_s:.0f} s ({run.time_s / 86_400:.3f} days){'' if run.converged else ' (time limit, not reached)'}")
        print(f"final state error: [{err[0]:.3e} m, {err[1]:.3e} m, {err[2]:.3e} rad]")
        print(f"path length: {run.path_length_m:.1f} m")
    return 0 if run.converged else 1


def add_study_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    """Register the `study` command; its handler returns the exit status."""
    p = subparsers.add_parser(
        "study", help="run the seed study end to end: navigation, path planning, localisation",
        description="Navigation P0 -> P1 with the moving-to-a-pose law, A* from P1 to P2 on a generated "
                    "crater map, and dead reckoning vs EKF localisation with a NEES Monte Carlo; writes "
                    "pose.png, crater_plan.png, localisation.png and summary.json into DIR.")
    p.add_argument("--out", metavar="DIR", default="study-out", help="output folder (default study-out)")
    p.add_argument("--seed", type=int, default=0, help="seed of the crater map and the noise (default 0)")
    p.add_argument("--runs", type=int, default=20, help="Monte Carlo runs for the NEES check (default 20)")
    p.set_defaults(func=run_study)
    return p


def study(out_dir: str, seed: int = 0, runs: int = 20) -> dict:
    """Run the three tasks, write the figures and summary.json into `out_dir`, return the summary."""
    import numpy as np

    from .crater import crater_map, path_is_clear, plan_on_map, plot_crater_plan
    from .ekf import nees_monte_carlo, plot_localisation, run_localisation
    from .pose import REPORT_TIME_S, plot_pose, simulate_pose

    os.makedirs(out_dir, exist_ok=True)
    pose = simulate_pose()
    route = np.stack([pose.x[::1000], pose.y[::1000]], axis=1)   # a point every 40 m
    cmap = crater_map(seed, keep_clear_path=route)
    plot_pose(pose, os.path.join(out_dir, "pose.png"), cmap.obstacles, cmap.scale_m)
    path = plan_on_map(cmap)
    plot_crater_plan(cmap, path, os.path.join(out_dir, "crater_plan.png"),
                     trajectory_xy=np.stack([pose.x[::100], pose.y[::100]], axis=1))
    loc = run_localisation(rng=seed)
    check = nees_monte_carlo(runs, seed=seed)
    plot_localisation(loc, os.path.join(out_dir, "localisation.png"), check)
    summary = {
        "navigation": {"time_s": pose.time_s, "time_days": pose.time_s / 86_400.0,
                       "report_time_days": REPORT_TIME_S / 86_400.0, "final_error": pose.final_error,
                       "path_length_m": pose.path_length_m, "converged": pose.converged,
                       "strongly_stable_gains": pose.gains.strongly_stable},
        "planning": {"pose_trajectory_clear": path_is_clear(cmap, route),"map_scale_m": cmap.scale_m, "map_shape": list(cmap.obstacles.shape), "seed": seed,
                     "length_m": path.length_m, "time_s": path.time_s, "waypoints": [list(w) for w in path.waypoints],
                     "clear": path_is_clear(cmap, path.waypoints)},
        "localisation": {**loc.summary(), "mc_runs": check.n_runs, "mc_mean_nees": check.mean,
                         "mc_nees_band": list(check.band), "mc_share_of_steps_in_band": check.inside},
    }
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
    return summary


def run_study(args: argparse.Namespace) -> int:
    """The `study` command's handler."""
    from ..planning import NoPathError

    t0 = time.perf_counter()
    try:
        s = study(args.out, args.seed, args.runs)
    except NoPathError as exc:
        print(f"rovernav study: no path on the crater map: {exc}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as exc:
        print(f"rovernav study: {exc}", file=sys.stderr)
        return 2
    nav, pl, loc = s["navigation"], s["planning"], s["localisation"]
    e = nav["final_error"]
    print(f"navigation P0 -> P1: {nav['time_days']:.3f} days (report 3.85), final error "
          f"[{e[0]:.2e} m, {e[1]:.2e} m, {e[2]:.2e} rad]")
    print(f"planning P1 -> P2: {pl['length_m'] / 1e3:.2f} km in {pl['time_s'] * 1e3:.1f} ms")
    print(f"localisation: final position error DR {loc['dr_final_position_error_m']:.2f} m, "
          f"EKF {loc['ekf_final_position_error_m']:.2f} m; mean NEES {loc['mc_mean_nees']:.2f} over "
          f"{loc['mc_runs']} runs (95 % band {loc['mc_nees_band'][0]:.2f}-{loc['mc_nees_band'][1]:.2f})")
    print(f"wrote {args.out}/pose.png, crater_plan.png, localisation.png, summary.json "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """`python -m rovernav.study.cli pose|study ...` (the same commands as in `rovernav`)."""
    parser = argparse.ArgumentParser(prog="rovernav-study")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_pose_parser(sub)
    add_study_parser(sub)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
