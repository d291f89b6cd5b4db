"""`rovernav calibrate rover`: the command itself (its flags are in calibrate/cli.py). The runs
driven (the simulated rover's, or the real one's under the camera), the motors' figures fitted
and printed with the configuration's values, or written into it."""

from __future__ import annotations

import json
import sys

from ..errors import InputError
from ..link import messages_gen as mg


def cmd_rover(args) -> int:
    from ..config import load_config
    from . import rover as cr

    if args.config is not None and not args.config.is_file():
        raise InputError(f"{args.config}: no such configuration file")
    if not args.sim and not args.port:
        raise InputError("give the rover's --port (and --camera), or --sim for the simulated rover")
    if args.setup is not None and not args.sim:
        raise InputError("--setup is a simulated set-up: give --sim with it")
    if args.camera is not None and args.sim:
        raise InputError("--camera watches the real rover: give --port with it, not --sim")
    if args.wall is not None and args.sim:
        raise InputError("--wall is where the real rover's wall is: the simulator's bench has its own (give --port)")
    cfg = load_config(args.config)
    if args.wall is not None:
        ax, ay = cfg.arena.width_m, cfg.arena.height_m
        if not all(-0.5 <= v <= lim + 0.5 for v, lim in zip(args.wall, (ax, ay, ax, ay))):
            raise InputError(f"--wall: {','.join(f'{v:g}' for v in args.wall)} is not in the {ax:g} x {ay:g} m arena")

    def progress(done: int, total: int) -> None:
        print(f"  run {done}/{total} done", file=sys.stderr)

    print(
        f"calibrating the rover's motors: {len(cr.LEVELS_PWM)} runs of {cr.RUN_M} m at "
        f"{', '.join(str(v) for v in cr.LEVELS_PWM)} PWM ...",
        file=sys.stderr,
    )
    try:
        if args.sim:
            from ..sim.setup import Setup

            if args.setup is not None and args.config is None:
                print(
                    "rovernav calibrate rover: --setup without --config: the default configuration does not see "
                    "that set-up's markers (calibrate the camera first: rovernav sim --setup SEED "
                    "--calibration-frames DIR)",
                    file=sys.stderr,
                )

            setup = Setup.random(args.setup) if args.setup is not None else None
            wall = cr.sim_bench(cfg)[2]
            runs = cr.runs_sim(cfg, setup=setup, progress=progress)
        else:
            wall = args.wall
            runs = cr.runs_hardware(
                args.port, args.camera, None if args.config is None else str(args.config), progress=progress, wall=wall
            )
        result = cr.fit(runs, wall, cfg.planner.sonar_cone_deg)
    except cr.CalibrationFailed as exc:
        print(f"rovernav calibrate rover: could not calibrate: {exc}", file=sys.stderr)
        return 1
    params = result.params()
    planner = result.planner()
    if args.write:
        cr.write_params(args.write, params, planner)
    before = {p: cfg.rover.get(p, mg.PARAMS[p].default) for p in params}
    planner_before = {k: getattr(cfg.planner, k) for k in planner}
    bias, sonar = result.gyro_bias, result.sonar
    if args.json:
        print(
            json.dumps(
                {
                    "mm_s_per_pwm": round(result.mm_s_per_pwm, 4),
                    "deadband_pwm": round(result.deadband_pwm, 2),
                    "right_gain": round(result.right_gain, 4),
                    "residual_mm_s": round(result.residual_mm_s, 2),
                    "right_gain_spread": round(result.gain_spread, 4),
                    "gyro_scale": None if result.gyro_scale is None else round(result.gyro_scale, 4),
                    "gyro_turns": result.gyro_turns,
                    "gyro_bias_dps": round(bias[0], 4) if isinstance(bias, tuple) else None,
                    "gyro_bias_se_dps": round(bias[1], 4) if isinstance(bias, tuple) else None,
                    "gyro_bias_not_measured": bias if isinstance(bias, str) else None,
                    "sonar_offset_m": round(sonar[0], 4) if isinstance(sonar, tuple) else None,
                    "sonar_offset_spread_m": round(sonar[1], 4) if isinstance(sonar, tuple) else None,
                    "sonar_echoes": sonar[2] if isinstance(sonar, tuple) else 0,
                    "sonar_not_measured": sonar if isinstance(sonar, str) else None,
                    "runs": [
                        {"level_pwm": lv, "speed_m_s": round(v, 4), "left_pwm": round(lp, 2), "right_pwm": round(rp, 2)}
                        for lv, v, lp, rp in result.runs
                    ],
                    "params": {mg.PARAMS[p].name: v for p, v in params.items()},
                    "before": {mg.PARAMS[p].name: v for p, v in before.items()},
                    "planner": planner,
                    "planner_before": planner_before,
                    "written": str(args.write) if args.write else None,
                }
            )
        )
        return 0
    for lv, v, lp, rp in result.runs:
        print(f"run      {lv:>3} PWM: {100 * v:5.1f} cm/s, commands left {lp:.1f} right {rp:.1f}")
    print(
        f"fit      speed {result.mm_s_per_pwm:.3f} mm/s per PWM above a dead band of {result.deadband_pwm:.1f} PWM "
        f"(line residual {result.residual_mm_s:.1f} mm/s); right motor {result.right_gain:.3f} x the left "
        f"(spread {result.gain_spread:.3f} over the runs)"
    )
    if result.gyro_scale is None:
        print(
            "gyro     scale not measured: no turn round was seen whole (the camera lost the rover, or a run "
            "ended early)"
        )
    else:
        off = 100 * (result.gyro_scale - 1)
        advice = (
            "" if abs(off) <= 5 else ": more than 5 % off: is the MPU6050 at its +-250 deg/s range, and mounted flat?"
        )
        print(
            f"gyro     reads {result.gyro_scale:.3f} x the camera's turn ({off:+.1f} %, over {result.gyro_turns} "
            f"turns, no fixes sent while it turned){advice}; no parameter takes it: the camera's fixes correct "
            "the heading"
        )
    if bias is None:
        print(
            f"gyro     bias not measured: the still {cr.STILL_S:g} s before the first run was not seen (did it start?)"
        )
    elif isinstance(bias, str):
        print(f"gyro     bias not measured: {bias}")
    else:
        advice = (
            ""
            if abs(bias[0]) <= cr.BIAS_WARN_DPS
            else f": more than {cr.BIAS_WARN_DPS} deg/s: was the rover moved in its first second? Power it up still; "
            "if it stays, the gyro drifts"
        )
        print(
            f"gyro     bias left after its start-up measure {bias[0]:+.3f} deg/s (+-{bias[1]:.3f}, still "
            f"{cr.STILL_S:g} s, no fix sent){advice}; no parameter takes it: the rover measures it at every start"
        )
    if sonar is None:
        print("sonar    offset not measured: give --wall (a wall the rover stands facing) to measure it")
    elif isinstance(sonar, str):
        print(f"sonar    offset not measured: {sonar}")
    else:
        print(
            f"sonar    {1000 * sonar[0]:.0f} mm ahead of the rover's centre, from {sonar[2]} echoes square to the "
            f"wall (spread {1000 * sonar[1]:.0f} mm)"
        )
    for p, v in params.items():
        change = "unchanged" if v == before[p] else f"was {before[p]}"
        print(f"param    {mg.PARAMS[p].name} = {v} ({change})")
    for k, v in planner.items():
        change = "unchanged" if v == round(planner_before[k], 3) else f"was {planner_before[k]:g}"
        print(f"param    [planner] {k} = {v:g} ({change})")
    if args.write:
        print(
            f"wrote    [rover] {', '.join(mg.PARAMS[p].name for p in params)}"
            + (f" and [planner] {', '.join(planner)}" if planner else "")
            + f" of {args.write}"
        )
    else:
        print("\n# for your configuration's [rover] table (or run again with --write FILE):")
        for p, v in params.items():
            print(f"{mg.PARAMS[p].name} = {v}")
        if planner:
            print("# and its [planner] table:")
            for k, v in planner.items():
                print(f"{k} = {v:g}")
    return 0
