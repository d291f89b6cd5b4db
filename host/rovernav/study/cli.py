"""`rovernav pose` and `rovernav study`: the seed study's tasks from the command line.

    rovernav pose                                   P0 → P1 with the report's gains, 4 cm/s
    rovernav pose --from 0 0 0 --to 10 5 1.57 --gains 0.5 1.2 -0.4 --vmax 0.3 --json
    rovernav study --out study-out --seed 0         all three tasks, figures and summary.json

Metres, radians (θ from the x axis, counter-clockwise), seconds. Exit status: 0 done; 1 the
pose was not reached within the time limit; 2 bad arguments (a value out of its limits, unstable
gains, a run that could not end within the limits) or no path on the crater map. Every limit
is checked before any work, and the simulation's steps are capped (validate.MAX_SIM_STEPS), so
no argument makes a run take unbounded time or memory.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

from ..files import strict_json_value
from ..validate import MAX_SIM_STEPS, ArgParser, check_number, number, output_file
from ..validate import out_dir as out_dir_type

MAX_RUNS = 200  # Monte Carlo runs of `study`: about 0.1 s each on this project's machine
MAX_SEED = 2**32 - 1


def dumps(value, **kwargs) -> str:
    """Strict JSON (no NaN or Infinity: null instead)."""
    return json.dumps(strict_json_value(value), allow_nan=False, **kwargs)


class _PoseAction(argparse.Action):
    """--from / --to: X and Y already checked by the type; THETA within ±MAX_THETA_RAD."""

    def __call__(self, parser, namespace, values, option_string=None):
        from .pose import MAX_THETA_RAD

        if abs(values[2]) > MAX_THETA_RAD:
            raise argparse.ArgumentError(
                self,
                f"THETA {values[2]:g} rad is outside -{MAX_THETA_RAD:g}..{MAX_THETA_RAD:g} rad (radians, not degrees)",
            )
        setattr(namespace, self.dest, list(values))


def _round_up(x: float, digits: int = 3) -> float:
    """`x` rounded up to `digits` significant figures."""
    if x <= 0:
        return x
    scale = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.ceil(x / scale) * scale


def add_pose_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    """Register the `pose` command; its handler returns the exit status."""
    from .pose import (
        CURIOSITY_VMAX_M_S,
        MAX_DT_S,
        MAX_GAIN,
        MAX_POSE_COORD_M,
        MAX_THETA_RAD,
        MAX_TIME_S,
        MAX_VMAX_M_S,
        MIN_DT_S,
        REPORT_P0,
        REPORT_P1,
        PoseGains,
    )

    g = PoseGains()
    coord = number(-MAX_POSE_COORD_M, MAX_POSE_COORD_M)
    km, days = MAX_POSE_COORD_M / 1e3, MAX_TIME_S / 86_400
    p = subparsers.add_parser(
        "pose",
        help="drive to a pose with the moving-to-a-pose law (the seed study's navigation task)",
        description="Simulate the moving-to-a-pose law (v = K_rho rho, omega = K_alpha alpha + K_beta beta) "
        "with Euler steps until the rover is within 0.1 m and 1e-3 rad of the goal pose; print "
        "the time taken and the final state error. A run gives up after "
        f"{days:g} simulated days or {MAX_SIM_STEPS:,} steps, whichever comes first (exit 1); "
        "a run that cannot end within those limits at the given speed and step is refused "
        "before it starts (exit 2), as are unstable gains.",
    )
    p.add_argument(
        "--from",
        dest="start",
        nargs=3,
        type=coord,
        action=_PoseAction,
        metavar=("X", "Y", "THETA"),
        default=list(REPORT_P0),
        help=f"start pose: X, Y in metres within +-{MAX_POSE_COORD_M:,.0f} ({km:g} km, twice the "
        f"report's crater map), THETA in radians within +-{MAX_THETA_RAD:g} "
        "(default the report's P0)",
    )
    p.add_argument(
        "--to",
        dest="goal",
        nargs=3,
        type=coord,
        action=_PoseAction,
        metavar=("X", "Y", "THETA"),
        default=list(REPORT_P1),
        help=f"goal pose, as --from: metres within +-{MAX_POSE_COORD_M:,.0f}, radians within "
        f"+-{MAX_THETA_RAD:g} (default the report's P1)",
    )
    p.add_argument(
        "--gains",
        nargs=3,
        type=number(-MAX_GAIN, MAX_GAIN),
        metavar=("KR", "KA", "KB"),
        default=[g.k_rho, g.k_alpha, g.k_beta],
        help=f"K_rho K_alpha K_beta in 1/s, each within +-{MAX_GAIN:g}, and stable: K_rho > 0, "
        "K_beta < 0, K_alpha > K_rho (default the report's Table 1: 0.1 0.145 -0.19)",
    )
    p.add_argument(
        "--vmax",
        type=number(0.0, MAX_VMAX_M_S, lo_open=True),
        default=CURIOSITY_VMAX_M_S,
        metavar="M_S",
        help=f"top speed in m/s, > 0 and <= {MAX_VMAX_M_S:g} (default 0.04, Curiosity)",
    )
    p.add_argument(
        "--dt",
        type=number(MIN_DT_S, MAX_DT_S),
        default=1.0,
        metavar="S",
        help=f"Euler step in seconds, {MIN_DT_S:g} to {MAX_DT_S:g} (default 1, the report's): longer "
        "steps make the heading update overshoot, shorter ones only add work; the run's "
        f"steps (its duration / dt) may not pass {MAX_SIM_STEPS:,}",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print {time_s, final_error, path_length_m, converged, strongly_stable} as strict JSON",
    )
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        type=_guarded(output_file(".png"), "a .png file name"),
        default=None,
        help="draw trajectory, v, theta and omega into a PNG file (a name ending in .png, in a "
        "folder that exists; written whole or not at all)",
    )
    p.set_defaults(func=run_pose)
    return p


def _fmt_duration(seconds: float) -> str:
    return f"{seconds:,.0f} s" if seconds < 86_400 else f"{seconds:,.0f} s ({seconds / 86_400:.3g} days)"


def check_pose_request(start, goal, gains, vmax: float, dt: float) -> None:
    """InputError, naming the flags and values, for a pose run that cannot end within the limits
    (MAX_TIME_S of simulated time, MAX_SIM_STEPS steps of `dt`), judged from a lower bound on its
    time (pose.min_time_s) before any work."""
    from ..errors import InputError
    from .pose import MAX_DT_S, MAX_TIME_S, min_time_s

    t_min = min_time_s(start, goal, gains.k_rho, vmax, dt)
    rho0 = math.hypot(goal[0] - start[0], goal[1] - start[1])
    trip = f"the {rho0:,.1f} m from --from to --to take at least {_fmt_duration(t_min)}"
    if t_min > MAX_TIME_S:
        raise InputError(
            f"--vmax {vmax:g} m/s with K_rho {gains.k_rho:g}: {trip}, more than a run's limit of "
            f"{_fmt_duration(MAX_TIME_S)}; a larger --vmax or K_rho, or a nearer --to"
        )
    steps = t_min / dt
    if steps > MAX_SIM_STEPS:
        need = _round_up(t_min / MAX_SIM_STEPS)
        fix = (
            f"a --dt of at least {need:.3g} s"
            if need <= MAX_DT_S
            else f"no --dt up to {MAX_DT_S:g} s is enough: a larger --vmax or K_rho, or a nearer --to"
        )
        raise InputError(
            f"--dt {dt:g}: {trip}: {steps:,.0f} steps of {dt:g} s, more than the limit of {MAX_SIM_STEPS:,}; {fix}"
        )


def run_pose(args: argparse.Namespace) -> int:
    """The `pose` command's handler."""
    from .pose import MAX_TIME_S, PoseGains, plot_pose, simulate_pose

    try:
        try:
            gains = PoseGains(*args.gains)
        except ValueError as exc:
            raise ValueError(f"--gains {' '.join(f'{k:g}' for k in args.gains)}: {exc}") from None
        check_pose_request(args.start, args.goal, gains, args.vmax, args.dt)
        run = simulate_pose(args.start, args.goal, gains, vmax=args.vmax, dt=args.dt)
    except ValueError as exc:  # InputError too
        print(f"rovernav pose: {exc}", file=sys.stderr)
        return 2
    if args.plot:
        try:
            plot_pose(run, args.plot)
        except OSError as exc:
            print(f"rovernav pose: --plot {args.plot}: cannot write it: {exc.strerror or exc}", file=sys.stderr)
            return 2
    err = run.final_error
    if args.json:
        print(
            dumps(
                {
                    "time_s": run.time_s,
                    "final_error": err,
                    "path_length_m": run.path_length_m,
                    "converged": run.converged,
                    "strongly_stable": gains.strongly_stable,
                }
            )
        )
    else:
        print(
            f"time: {run.time_s:.0f} s ({run.time_s / 86_400:.3f} days){'' if run.converged else f' (not reached: stopped at the limit of {MAX_TIME_S / 86_400:g} days or {MAX_SIM_STEPS:,} steps)'}"
        )
        print(f"final state error: [{err[0]:.3e} m, {err[1]:.3e} m, {err[2]:.3e} rad]")
        print(f"path length: {run.path_length_m:.1f} m")
    return 0 if run.converged else 1


def _guarded(parse, what: str):
    """An argparse type that turns the OverflowError or OSError `parse` may raise on a hostile
    value (an integer too large for a float, a file name too long for the system) into the usual
    one-line refusal."""

    def guarded(text: str):
        try:
            return parse(text)
        except (OverflowError, OSError) as exc:
            short = text if len(text) <= 40 else text[:40] + "..."
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else f"must be {what}"
            raise argparse.ArgumentTypeError(f"{short!r}: {reason}") from None

    guarded.__name__ = getattr(parse, "__name__", "value")
    return guarded


def _integer(lo: int, hi: int):
    """validate.number(lo, hi, integer=True), refusing in one line an integer too large for a float."""
    return _guarded(number(lo, hi, integer=True), f"an integer >= {lo:,} and <= {hi:,}")


def add_study_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    """Register the `study` command; its handler returns the exit status."""
    p = subparsers.add_parser(
        "study",
        help="run the seed study end to end: navigation, path planning, localisation",
        description="Navigation P0 -> P1 with the moving-to-a-pose law, A* from P1 to P2 on a generated "
        "crater map, and dead reckoning vs EKF localisation with a NEES Monte Carlo; writes "
        "pose.png, crater_plan.png, localisation.png and summary.json (strict JSON) into DIR. "
        "Everything is computed before anything is written, and each file is written whole "
        "or not at all.",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        type=out_dir_type,
        default="study-out",
        help="output folder, made if missing; not an existing file (default study-out)",
    )
    p.add_argument(
        "--seed",
        type=_integer(0, MAX_SEED),
        default=0,
        help=f"seed of the crater map and the noise, an integer 0 to {MAX_SEED} (default 0)",
    )
    p.add_argument(
        "--runs",
        type=_integer(1, MAX_RUNS),
        default=20,
        help=f"Monte Carlo runs for the NEES check, an integer 1 to {MAX_RUNS} (about 0.1 s each; default 20)",
    )
    p.set_defaults(func=run_study)
    return p


def study(out_dir: str | os.PathLike, seed: int = 0, runs: int = 20) -> dict:
    """Run the three tasks, write the figures and summary.json into `out_dir`, return the summary.

    Everything is computed first, so a failure (no path on the map, a bad argument) leaves the
    folder as it was; each file is then written atomically. InputError for a seed or a number of
    runs outside the limits, or an `out_dir` that is a file.
    """
    import numpy as np

    from ..errors import InputError
    from ..files import write_atomic
    from .crater import crater_map, path_is_clear, plan_on_map, plot_crater_plan
    from .ekf import nees_monte_carlo, plot_localisation, run_localisation
    from .pose import REPORT_TIME_S, plot_pose, simulate_pose

    seed = check_number("--seed", seed, 0, MAX_SEED, integer=True)
    runs = check_number("--runs", runs, 1, MAX_RUNS, integer=True)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")

    pose = simulate_pose()
    route = np.stack([pose.x[::1000], pose.y[::1000]], axis=1)  # a point every 40 m
    cmap = crater_map(seed, keep_clear_path=route)
    path = plan_on_map(cmap)
    loc = run_localisation(rng=seed)
    check = nees_monte_carlo(runs, seed=seed)
    summary = {
        "navigation": {
            "time_s": pose.time_s,
            "time_days": pose.time_s / 86_400.0,
            "report_time_days": REPORT_TIME_S / 86_400.0,
            "final_error": pose.final_error,
            "path_length_m": pose.path_length_m,
            "converged": pose.converged,
            "strongly_stable_gains": pose.gains.strongly_stable,
        },
        "planning": {
            "pose_trajectory_clear": path_is_clear(cmap, route),
            "map_scale_m": cmap.scale_m,
            "map_shape": list(cmap.obstacles.shape),
            "seed": seed,
            "length_m": path.length_m,
            "time_s": path.time_s,
            "waypoints": [list(w) for w in path.waypoints],
            "clear": path_is_clear(cmap, path.waypoints),
        },
        "localisation": {
            **loc.summary(),
            "mc_runs": check.n_runs,
            "mc_mean_nees": check.mean,
            "mc_nees_band": list(check.band),
            "mc_share_of_steps_in_band": check.inside,
        },
    }
    summary = strict_json_value(summary)
    text = json.dumps(summary, indent=2, allow_nan=False)

    os.makedirs(out, exist_ok=True)
    plot_pose(pose, out / "pose.png", cmap.obstacles, cmap.scale_m)
    plot_crater_plan(
        cmap, path, out / "crater_plan.png", trajectory_xy=np.stack([pose.x[::100], pose.y[::100]], axis=1)
    )
    plot_localisation(loc, out / "localisation.png", check)
    write_atomic(out / "summary.json", text + "\n")  # last: its presence means the set is complete
    return summary


def run_study(args: argparse.Namespace) -> int:
    """The `study` command's handler."""
    from ..planning import NoPathError

    t0 = time.perf_counter()
    try:
        s = study(args.out, args.seed, args.runs)
    except NoPathError as exc:
        print(f"rovernav study: no path on the crater map of --seed {args.seed}: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # InputError too
        print(f"rovernav study: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = exc.filename or args.out
        print(f"rovernav study: --out {args.out}: cannot write {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    nav, pl, loc = s["navigation"], s["planning"], s["localisation"]
    e = nav["final_error"]
    print(
        f"navigation P0 -> P1: {nav['time_days']:.3f} days (report 3.85), final error "
        f"[{e[0]:.2e} m, {e[1]:.2e} m, {e[2]:.2e} rad]"
    )
    print(f"planning P1 -> P2: {pl['length_m'] / 1e3:.2f} km in {pl['time_s'] * 1e3:.1f} ms")
    print(
        f"localisation: final position error DR {loc['dr_final_position_error_m']:.2f} m, "
        f"EKF {loc['ekf_final_position_error_m']:.2f} m; mean NEES {loc['mc_mean_nees']:.2f} over "
        f"{loc['mc_runs']} runs (95 % band {loc['mc_nees_band'][0]:.2f}-{loc['mc_nees_band'][1]:.2f})"
    )
    print(
        f"wrote {args.out}/pose.png, crater_plan.png, localisation.png, summary.json ({time.perf_counter() - t0:.1f} s)"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    """`python -m rovernav.study.cli pose|study ...` (the same commands as in `rovernav`)."""
    parser = ArgParser(prog="rovernav-study")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=ArgParser)
    add_pose_parser(sub)
    add_study_parser(sub)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
