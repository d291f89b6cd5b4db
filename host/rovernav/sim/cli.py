"""`rovernav sim`: run a mission in the simulator and write its report, video and picture."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..radio_flags import add_radio_flags, radio_from_args, radio_line
from ..validate import MAX_SIM_TIME_S, input_file, number, out_dir, seconds, time_window
from ..vehicle_gen import LINK_BAUD

# What a run writes into its folder (and a new run there first removes).
RESULT_FILES = ("report.json", "summary.png", "video.mp4", "run.mcap", "comparison.json")


def add_sim_parser(sub) -> None:
    p = sub.add_parser(
        "sim",
        help="run a mission in the simulator (the main job without hardware)",
        description="Simulate a mission: the firmware core the Uno runs (through its C ABI), a rover plant "
        "with motor lag and dead band, a drifting gyro, an HC-SR04 on a servo, an overhead camera "
        f"rendering 640x480 frames that the host's vision code reads, and a {LINK_BAUD:,}-baud radio; the "
        "host is the same mission code `rovernav run` uses. Writes report.json, video.mp4, "
        "summary.png and run.mcap (the run log: open it in Foxglove, or `rovernav replay` it) "
        "into the output folder; --live shows the run in Foxglove as it happens.",
        epilog="Strategies: rovernav (the autonomy on the rover, simplified paths, fast sweeps) and seed (the "
        "2019 system's behaviour: a stop at every grid waypoint, 9-second sweeps); both runs them in the "
        "same world and prints them side by side.",
    )
    p.add_argument(
        "scenario",
        nargs="?",
        default="out-and-back",
        help="a scenario name (see scenarios/) or a scenario file (default: out-and-back)",
    )
    p.add_argument(
        "--out",
        type=out_dir,
        default=Path("out/sim"),
        help="output folder (default out/sim); a run first removes the previous run's results there",
    )
    p.add_argument(
        "--seed",
        type=number(0, 2**32 - 1, integer=True),
        default=1,
        help="random seed, 0 to 2^32-1: noise, light, drops (default 1)",
    )
    p.add_argument("--strategy", choices=("rovernav", "seed", "both"), default="rovernav")
    p.add_argument(
        "--drive-mode",
        choices=("rotate_drive", "pose_law", "both"),
        default=None,
        help="how the rover drives between waypoints: the seed's rotate-then-drive, or the "
        "moving-to-a-pose law (arcs, a heading at each waypoint); both runs each and says "
        "which was faster (default: the configuration's [rover] drive_mode, else rotate_drive)",
    )
    p.add_argument("--no-video", action="store_true", help="skip the video (faster)")
    p.add_argument(
        "--config", type=input_file, help="a rovernav TOML configuration (vision, planner, rover parameters)"
    )
    p.add_argument(
        "--max-time",
        type=seconds(MAX_SIM_TIME_S, positive=True),
        default=900.0,
        help=f"give up after this many simulated seconds, up to {MAX_SIM_TIME_S:g} (default 900)",
    )
    p.add_argument(
        "--camera-fps", type=number(1.0, 120.0), default=30.0, help="camera frame rate, 1 to 120 (default 30)"
    )
    p.add_argument(
        "--rovers",
        type=number(1, 4, integer=True),
        default=None,
        help="a fleet of N rovers, 1 to 4, under one camera on one half-duplex radio: rover k starts at the "
        "scenario's k-th start ([start], then [[starts]]) and shuttles to its site ([target], then "
        "[[sites]], in turn); a scenario with fewer starts is refused (try fleet-out-and-back). Each rover "
        "has its own ArUco tag, key and radio address; the host gives each its slot on the air, plans "
        "each round the others and holds one still for another (report.json: per-rover and fleet figures)",
    )
    p.add_argument(
        "--trips",
        type=number(1, 100, integer=True),
        default=None,
        help="round trips each rover of a fleet makes (default: the scenario's [mission] trips)",
    )
    p.add_argument(
        "--rover-configs",
        type=input_file,
        nargs="+",
        metavar="FILE",
        help="with --rovers: each rover's own configuration file, rover 1's first (as `rovernav run --rovers N "
        "--rover-configs` takes them): its [rover] parameters over --config's",
    )
    p.add_argument(
        "--no-host-replan",
        action="store_true",
        help="the host never replans: only the rover's own detours get it round obstacles",
    )
    p.add_argument(
        "--link-outage",
        type=time_window,
        action="append",
        default=[],
        metavar="START:DURATION",
        help="no bytes either way on the radio for DURATION seconds from START (repeatable)",
    )
    p.add_argument(
        "--camera-outage",
        type=time_window,
        action="append",
        default=[],
        metavar="START:DURATION",
        help="the camera delivers nothing (or see --camera-outage-kind) for a while (repeatable)",
    )
    p.add_argument("--camera-outage-kind", choices=("no_frames", "no_markers"), default="no_frames")
    p.add_argument(
        "--host-restart",
        type=seconds(),
        action="append",
        default=[],
        metavar="T",
        help="restart the host process state at T seconds (repeatable)",
    )
    p.add_argument(
        "--firmware-reset",
        type=seconds(),
        action="append",
        default=[],
        metavar="T",
        help="reset the rover's firmware at T seconds (repeatable)",
    )
    p.add_argument("--gyro-dies", type=seconds(), metavar="T", help="the gyro stops answering at T seconds")
    p.add_argument(
        "--unsigned",
        action="store_true",
        help="run the link unsigned (no key on either end). By default host and rover share a "
        "128-bit link key, as after `rovernav keygen` and `rovernav provision`: every frame "
        "but HELLO carries a counter and a SipHash-2-4 tag, and each end refuses the rest "
        "(report.json: link.signing)",
    )
    p.add_argument(
        "--attacker",
        action="store_true",
        help="a second transmitter on the rover's frequency: from 3 s on it injects, every 0.5 s, "
        "a forged STOP, a replay of a frame the host sent, a recorded frame altered in one "
        "bit, and an unsigned STOP, in turn. report.json's link.signing.attacker counts "
        "what it injected and what the rover refused",
    )
    p.add_argument(
        "--rover",
        choices=("native", "uno"),
        default="native",
        help="the rover's firmware: native (default) steps the firmware core through its C ABI, "
        "built for this machine; uno runs the Uno image itself (build/uno/firmware.elf, "
        "built if missing) in simavr at 16 MHz, with the world on its pins: motor PWM "
        "registers, the servo's Timer1 pulse, HC-SR04 TRIG/ECHO, an MPU-6050 on the TWI bus, "
        f"the UART at {LINK_BAUD:,} baud. uno runs several times faster than real time (about 9x "
        "without video on a 2-core machine, native about 15x; the harness skips the image's "
        'idle polling, cycle-exactly), and adds "uno_timing" to report.json: step times per '
        "state and per flag (from the image's PB0 probe and GPIOR0 step descriptor), the worst "
        "step and where it was, the step period's jitter, and the stack's high-water mark. "
        "Needs gcc-avr, avr-libc, arduino-core-avr and libsimavr-dev",
    )
    p.add_argument(
        "--profile",
        action="store_true",
        help="with --rover uno: profile the image's steps by function. While a step works (PB0 high) "
        "the harness counts every instruction's cycles to the function whose ELF symbol holds its "
        "PC (exact, not sampled), interrupt handlers apart, and follows CALL and RET for inclusive "
        'times and callers. Writes uno_timing["profile"] to report.json: for all steps, the steps '
        "with a FIX, with sonar, with the detour planner, with radio bytes, with none of those, and "
        "the worst 1 %% and the worst step: the top 15 functions with their share of the step time, microseconds and "
        "calls per step, the interrupts, and the float and integer library routines with their "
        "callers. Prints the top 10 for the steps with a FIX. Off by default: the AVR simulation "
        "runs about a third slower",
    )
    add_radio_flags(p)
    from ..runlog.cli import add_log_flags

    add_log_flags(p, "run.mcap in the output folder")
    p.add_argument(
        "--speed",
        type=number(0.01, 1000.0),
        default=None,
        metavar="X",
        help="run at X times real time (default: as fast as the machine goes; with --live, 1: the "
        "live view shows the mission at its own pace)",
    )
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    p.add_argument(
        "--camera-process",
        choices=("auto", "on", "off"),
        default="auto",
        help="render and locate the camera's frames in a second process, beside the mission's loop: "
        "the same frames and fixes, faster on a machine with a core to spare; never with a video, "
        "which needs the frames in the loop. auto (the default): on when the run writes no video "
        "and the machine has two usable cores",
    )
    p.add_argument(
        "--setup",
        type=number(0, 2**32 - 1, integer=True),
        metavar="SEED",
        help="a set-up that is not the defaults, drawn from SEED: other marker colours, light, a tilted "
        "camera, motors and gyro off the firmware's figures (rovernav.sim.setup); the default "
        "configuration does not see its rover: calibrate with --calibration-frames",
    )
    p.add_argument(
        "--calibration-frames",
        type=out_dir,
        metavar="DIR",
        help="with --setup: write three camera frames of the scenario's start into DIR for "
        "`rovernav calibrate camera`, print that command, and run no mission",
    )
    p.set_defaults(func=cmd_sim)


def _write_calibration_frames(args, scenario, setup) -> int:
    """`rovernav sim --setup SEED --calibration-frames DIR`: frames to calibrate from, and the command."""
    import cv2

    if setup is None:
        print(
            "rovernav sim: --calibration-frames needs --setup SEED (the default set-up is the configuration's)",
            file=sys.stderr,
        )
        return 2
    args.calibration_frames.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, frame in enumerate(setup.calibration_frames(scenario, 3, rng_seed=args.setup)):
        path = args.calibration_frames / f"frame-{i + 1}.png"
        cv2.imwrite(str(path), frame)
        paths.append(str(path))
    words = " ".join(f"--{role.split('_')[-1]} {word}" for role, word in setup.colour_words().items())
    print(
        f"wrote {len(paths)} frames of set-up {args.setup} ({scenario.name} at its start) in {args.calibration_frames}"
    )
    print(
        f"calibrate:  rovernav calibrate camera {' '.join(paths)} {words} "
        f"--write {args.calibration_frames / 'calibrated.toml'}"
    )
    print(
        f"then fly:   rovernav sim {args.scenario} --setup {args.setup} "
        f"--config {args.calibration_frames / 'calibrated.toml'}"
    )
    return 0


def cmd_sim(args: argparse.Namespace) -> int:
    from ..config import load_config
    from ..cores import FirmwareBuildError
    from ..evaluation.report import VideoWriter, build_report, summary_picture, write_report
    from ..files import remove_stale, write_json_atomic
    from ..runlog.cli import live_port_of
    from ..runlog.writer import RunLogError
    from ..scenario import ScenarioError, load_scenario
    from .camera_process import spare_core
    from .runner import Faults, SimOptions, Simulation

    if args.profile and args.rover != "uno":
        print("rovernav sim: --profile profiles the Uno image: it needs --rover uno", file=sys.stderr)
        return 2
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        print(f"rovernav sim: {exc}", file=sys.stderr)
        return 2
    config = load_config(args.config) if args.config else None
    setup = None
    if args.setup is not None:
        from .setup import Setup

        setup = Setup.random(args.setup)
    if args.calibration_frames is not None:
        return _write_calibration_frames(args, scenario, setup)
    channel = radio_from_args(args, config.radio if config else None, f"{args.config}: " if args.config else "")
    if args.rovers is not None:
        return cmd_sim_fleet(args, scenario, config, channel)
    if args.rover_configs:
        print("rovernav sim: --rover-configs is for a fleet (--rovers N); one rover's are --config's", file=sys.stderr)
        return 2
    strategies = ["rovernav", "seed"] if args.strategy == "both" else [args.strategy]
    modes = ["rotate_drive", "pose_law"] if args.drive_mode == "both" else [args.drive_mode]  # None: the config's
    runs = [(st, mode) for st in strategies for mode in modes]
    if len(runs) > 1:
        remove_stale(args.out, ("comparison.json",))
    reports = []
    for strategy, mode in runs:
        name = strategy if len(modes) == 1 else (mode if len(strategies) == 1 else f"{strategy}-{mode}")
        out = args.out / name if len(runs) > 1 else args.out
        out.mkdir(parents=True, exist_ok=True)
        remove_stale(out, RESULT_FILES)  # never the last run's results beside this one's
        faults = Faults(
            link_outages=args.link_outage,
            camera_outages=args.camera_outage,
            camera_outage_kind=args.camera_outage_kind,
            host_restarts=args.host_restart,
            firmware_resets=args.firmware_reset,
            gyro_dies_at=args.gyro_dies,
        )
        opts = SimOptions(
            camera_process=args.camera_process == "on"
            or (args.camera_process == "auto" and args.no_video and spare_core()),
            seed=args.seed,
            strategy=strategy,
            camera_fps=args.camera_fps,
            max_time_s=args.max_time,
            host_replan=not args.no_host_replan,
            faults=faults,
            config=config,
            drive_mode=mode,
            rover=args.rover,
            signed=not args.unsigned,
            attacker=args.attacker,
            channel=channel,
            log=None if args.no_log else out / "run.mcap",
            live_port=live_port_of(args),
            log_image_hz=args.log_image_hz,
            setup=setup,
            pace=args.speed if args.speed is not None else (1.0 if args.live else 0.0),
        )
        video = None if args.no_video else VideoWriter(out / "video.mp4", args.camera_fps)
        started = time.monotonic()

        def progress(t, text, _started=started, _strategy=strategy):
            if args.quiet:
                return
            if text is None:
                wall = time.monotonic() - _started
                print(f"  ... {t:6.1f} s simulated ({t / max(wall, 1e-9):.0f}x real time)", file=sys.stderr, flush=True)
            else:
                print(f"[{_strategy} {t:7.2f} s] {text}", flush=True)

        try:
            sim = Simulation(scenario, opts, frame_sink=video, progress=progress)
        except (FirmwareBuildError, RunLogError) as exc:
            if video is not None:
                video.close(keep=False)
            print(f"rovernav sim: {exc}", file=sys.stderr)
            return 2
        if not args.quiet:
            print(
                f"simulating {scenario.name} with the {strategy} strategy, {sim.drive_mode} (seed {args.seed}) ...",
                flush=True,
            )
        if sim.runlog is not None and sim.runlog.live_port is not None:
            print(
                f"live view: open Foxglove and connect to ws://localhost:{sim.runlog.live_port} "
                f"(running at {opts.pace:g}x real time)",
                flush=True,
            )
        if args.profile:
            try:
                sim.core.enable_profile()  # before the first step: the image has not run yet
            except FirmwareBuildError as exc:
                print(f"rovernav sim: {exc}", file=sys.stderr)
                return 2
        try:
            sim.run()
        except BaseException:
            # Ctrl-C or an error mid-run: no half video; a report that says the run was cut short.
            if video is not None:
                video.close(keep=False)
            sim.close_log({"interrupted": True})  # the log of a run cut short is kept: it says how it ended
            try:
                cut = build_report(sim, time.monotonic() - started)
                cut.update(outcome="interrupted", interrupted=True, reached=False)
                write_report(cut, out / "report.json")
            except Exception:  # noqa: BLE001 - the report is a courtesy; the original error matters
                pass
            raise
        if video is not None:
            video.close()
        sim.close_log()
        report = build_report(sim, time.monotonic() - started)
        if args.rover == "uno":
            report["uno_timing"] = sim.uno_timing()
            print(_uno_line(report["uno_timing"]))
            if "profile" in report["uno_timing"]:
                print(_uno_profile_table(report["uno_timing"]["profile"]))
        write_report(report, out / "report.json")
        summary_picture(sim, report, out / "summary.png")
        reports.append(report)
        print(_summary_line(report))
        if radio_line(report):
            print(radio_line(report))
        print(
            f"  wrote {out / 'report.json'}, {out / 'summary.png'}"
            + ("" if video is None else f", {out / 'video.mp4'}")
            + ("" if opts.log is None else f", {opts.log}")
        )
    if len(reports) > 1:
        print()
        print(comparison_table(reports))
        done = [r for r in reports if r["reached"]]
        if len(modes) > 1 and done:
            best = min(done, key=lambda r: r["mission_time_s"])
            print(f"faster: {best['strategy']} / {best['drive_mode']} ({best['mission_time_s']:.1f} s)")
        write_json_atomic(args.out / "comparison.json", reports)
    return 0 if all(r["reached"] and r["collisions"] == 0 for r in reports) else 1


def _summary_line(r: dict) -> str:
    from ..evaluation.report import fmt_m, outcome_text

    ok = outcome_text(r)
    return (
        f"{r['scenario']} / {r['strategy']} / {r['drive_mode']}: {ok} in {r['mission_time_s']:.1f} s simulated "
        f"({r['wall_time_s']:.1f} s wall, {r['speedup']}x), driven {r['path_length_m']:.2f} m "
        f"(clairvoyant optimum {fmt_m(r['optimal_length_m'])}), SPL {r['spl']:.2f}, "
        f"collisions {r['collisions']}, min clearance {r['min_clearance_m']} m, replans {r['replans']}"
        + (f"; error: {r['error']}" if r.get("error") else "")
    )


def _uno_line(t: dict) -> str:
    speed, stack, worst = t["speed"], t["stack"], t["worst_step"]
    line = (
        f"  uno: {t['steps']} steps, AVR simulated at {speed['avr_x_real_time']}x real time "
        f"({speed['idle_fast_forward_share'] or 0:.0%} of cycles fast-forwarded idle), "
        f"stack {stack['used_bytes']} bytes used, {stack['margin_bytes']} to spare"
    )
    if worst:
        line += f"; worst step {worst['us'] / 1000:.2f} ms at {worst['t_s']:.2f} s" + (
            f" ({worst['state']}{', ' + '+'.join(worst['flags']) if worst['flags'] else ''})" if worst["state"] else ""
        )
    if t["period_jitter"]["max_abs_us"] is not None:
        line += f"; period jitter max {t['period_jitter']['max_abs_us'] / 1000:.2f} ms"
    if not t["hooks"]["step_probe_pb0"]:
        line += "; the image has no PB0 step probe: no step times"
    return line


def _uno_profile_table(prof: dict, kind: str = "fix", rows: int = 10) -> str:
    """The top functions of one kind of step (default: the steps with a FIX), by self cycles."""
    k = prof["kinds"].get(kind) or {}
    if not k.get("steps"):
        return f"  uno profile: no steps of kind {kind!r}"
    lines = [
        f"  uno profile, steps with {'a FIX' if kind == 'fix' else kind}: {k['steps']} steps, mean "
        f"{k['mean_step_us'] / 1000:.2f} ms; {k['named_share']:.1%} of their cycles in named functions, "
        f"interrupts {k['interrupt_share']:.1%}, float library {k['float_library']['share']:.1%} "
        f"({k['float_library']['us_per_step']:.0f} us/step), integer library {k['integer_library']['share']:.1%}",
        f"  {'self':>7} {'us/step':>8} {'calls':>6} {'incl us':>8}  function (self: at its own PCs; incl: CALL to RET)",
    ]
    for r in k["functions"][:rows]:
        incl = r.get("inclusive_us_per_step")
        lines.append(
            f"  {r['share']:>7.1%} {r['us_per_step']:>8.1f} {r['calls_per_step']:>6.2f} "
            f"{'' if incl is None else f'{incl:.1f}':>8}  {r['function']}"
        )
    return "\n".join(lines)


def comparison_table(reports: list[dict]) -> str:
    from ..evaluation.report import fmt_m

    rows = [
        ("", *[f"{r['strategy']}/{r['drive_mode']}" for r in reports]),
        ("outcome", *[r["outcome"] for r in reports]),
        ("mission time (s)", *[f"{r['mission_time_s']:.1f}" for r in reports]),
        ("path length (m)", *[f"{r['path_length_m']:.2f}" for r in reports]),
        ("clairvoyant optimum", *[fmt_m(r["optimal_length_m"]) for r in reports]),
        ("SPL", *[f"{r['spl']:.2f}" for r in reports]),
        ("replans", *[str(r["replans"]) for r in reports]),
        ("collisions", *[str(r["collisions"]) for r in reports]),
        ("min clearance (m)", *[str(r["min_clearance_m"]) for r in reports]),
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)) for row in rows)


# ---------------------------------------------------------------- a fleet (--rovers N)

#: What `rovernav sim` can do for one rover and not yet for a fleet: said in one line.
_LONE_ONLY = (
    ("strategy", "rovernav", "--strategy"),
    ("drive_mode", None, "--drive-mode"),
    ("link_outage", [], "--link-outage"),
    ("camera_outage", [], "--camera-outage"),
    ("host_restart", [], "--host-restart"),
    ("firmware_reset", [], "--firmware-reset"),
    ("gyro_dies", None, "--gyro-dies"),
    ("attacker", False, "--attacker"),
    ("live", False, "--live"),
    ("setup", None, "--setup"),
    ("profile", False, "--profile"),
    ("calibration_frames", None, "--calibration-frames"),
)


def cmd_sim_fleet(args: argparse.Namespace, scenario, config, channel) -> int:
    import dataclasses

    from ..evaluation.report import VideoWriter
    from ..files import remove_stale, write_json_atomic
    from ..scenario import ScenarioError
    from .fleet_runner import FleetOptions, FleetSimulation, fleet_summary

    for attr, lone, flag in _LONE_ONLY:
        if getattr(args, attr, lone) not in (lone, None) and getattr(args, attr, lone) != lone:
            print(
                f"rovernav sim: {flag} is for one rover; a fleet (--rovers {args.rovers}) runs without it",
                file=sys.stderr,
            )
            return 2
    from ..fleet.run import fleet_rover_params

    own = fleet_rover_params(args.rover_configs, args.rovers, config)  # InputError, ConfigError: one line
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    remove_stale(out, ("report.json", "summary.png", "video.mp4", "run.mcap", "comparison.json"))
    opts = FleetOptions(
        rovers=args.rovers,
        seed=args.seed,
        camera_fps=args.camera_fps,
        max_time_s=args.max_time,
        trips=args.trips,
        channel=dataclasses.replace(channel, half_duplex=True),
        config=config,
        signed=not args.unsigned,
        rover1=args.rover,  # --rover uno: rover 1 is the Uno image
        log=None if args.no_log else out / "run.mcap",  # a channel set per rover (runlog/fleet.py)
        log_image_hz=args.log_image_hz,
        rover_params=own,
    )

    def progress(t: float, text: str | None) -> None:
        if args.quiet:
            return
        if text is None:
            print(f"  ... {t:6.1f} s simulated", file=sys.stderr, flush=True)
        else:
            print(f"[fleet {t:7.2f} s] {text}", flush=True)

    from ..runlog.writer import RunLogError

    try:
        sim = FleetSimulation(scenario, opts, progress=progress)
    except (ScenarioError, RunLogError) as exc:
        print(f"rovernav sim: {exc}", file=sys.stderr)
        return 2
    video = None if args.no_video else VideoWriter(out / "video.mp4", args.camera_fps)
    if video is not None:
        sim.frame_sink = lambda t, frame: video.write(frame)
    if not args.quiet:
        print(f"simulating {scenario.name} with {args.rovers} rovers (seed {args.seed}) ...", flush=True)
    started = time.monotonic()
    try:
        sim.run()
    except BaseException:
        if video is not None:
            video.close(keep=False)
        sim.close_log({"interrupted": True})  # the log of a run cut short is kept: it says how it ended
        raise
    if video is not None:
        video.close()
    report = sim.report()
    report["scenario"] = scenario.name
    report["seed"] = args.seed
    report["wall_time_s"] = round(time.monotonic() - started, 1)
    report["speedup"] = round(sim.t / max(report["wall_time_s"], 1e-9), 1)
    sim.close_log(report)
    write_json_atomic(out / "report.json", report)
    from .fleet_picture import fleet_picture

    fleet_picture(sim, report, out / "summary.png")
    print(fleet_summary(report))
    timing = report.get("uno_timing")
    if timing:
        worst = timing.get("worst_step") or {}
        print(f"  rover 1, the Uno image: worst step {worst.get('us', 0) / 1000:.2f} ms (of the 5 ms allowed)")
    print(
        f"  wrote {out / 'report.json'}, {out / 'summary.png'}"
        + ("" if video is None else f", {out / 'video.mp4'}")
        + ("" if opts.log is None else f", {opts.log} (a channel set per rover: /rover1/..., /rover2/...)")
    )
    return 0 if report["outcome"] == "reached" and report["contacts"] == 0 else 1
