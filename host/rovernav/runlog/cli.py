"""`rovernav replay LOG.mcap`, and the flags `rovernav sim` and `rovernav run` share for their logs."""

from __future__ import annotations

import argparse
import sys
import time

from ..validate import input_file, number, output_file

#: Highest port number accepted for the live view.
MAX_PORT = 65535


def live_port(text: str) -> int:
    """An argparse type: a TCP port 0 to 65535 (0: any free one)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number (0 to {MAX_PORT})") from None
    if not 0 <= value <= MAX_PORT:
        raise argparse.ArgumentTypeError(f"{text!r}: a port is 0 to {MAX_PORT} (0: any free one)")
    return value


def add_log_flags(p: argparse.ArgumentParser, default_log: str) -> None:
    """--no-log, --log-image-hz, --live [PORT] for a command that runs a mission."""
    from .channels import DEFAULT_IMAGE_HZ, DEFAULT_LIVE_PORT

    p.add_argument(
        "--no-log",
        action="store_true",
        help=f"do not write the run log ({default_log}: an MCAP file with every frame on the link both "
        "ways, raw and decoded, the camera's fixes and some of its images, the paths planned and "
        "driven, the learned map, sonar echoes and events, in Foxglove's schemas; "
        "`rovernav replay` reads it)",
    )
    p.add_argument(
        "--log-image-hz",
        type=number(0.0, 30.0),
        default=DEFAULT_IMAGE_HZ,
        metavar="HZ",
        help=f"camera images kept in the log (and sent live) per second, 0 to 30; 0 keeps none "
        f"(default {DEFAULT_IMAGE_HZ:g}; the fixes are all kept)",
    )
    p.add_argument(
        "--live",
        action="store_true",
        help=f"serve the log's channels live over Foxglove's WebSocket protocol on 127.0.0.1 (port "
        f"{DEFAULT_LIVE_PORT}, or --live-port): in Foxglove, 'Open connection', "
        f"ws://localhost:{DEFAULT_LIVE_PORT}. The server takes only a client that offers the "
        "foxglove.sdk.v1 subprotocol: one that offers only foxglove.websocket.v1 (older Foxglove "
        "and Lichtblick builds) gets HTTP 400",
    )
    p.add_argument(
        "--live-port",
        type=live_port,
        default=DEFAULT_LIVE_PORT,
        metavar="PORT",
        help=f"the live view's port, 0 to {MAX_PORT} (0: any free one; default {DEFAULT_LIVE_PORT})",
    )


def live_port_of(args: argparse.Namespace) -> int | None:
    """The port to serve the live view on (None: no live view)."""
    return args.live_port if args.live else None


def add_replay_parser(sub) -> None:
    p = sub.add_parser(
        "replay",
        help="run the host's mission code again against a recorded run",
        description="Read a run log (run.mcap, written by `rovernav sim` and `rovernav run`), build the host's "
        "mission again from what the log says it was made of, feed it every input it had (its ticks, "
        "the camera's detections, each frame it took from the rover) at the recorded times, with no "
        "rover, camera or simulator, and compare what it sends with what the recorded host sent: "
        "message by message and path by path. The same code and settings give the same decisions; "
        "with --set (or changed planner code) it shows where the host would have decided "
        "differently. After the first difference the recorded rover is still answering the "
        "recorded host: replay is open loop from there.",
        epilog="Exit status: 0 the replayed host decided exactly as recorded; 1 it decided differently (the "
        "differences are printed); 2 the file is not a run log this rovernav can replay, or a --set is "
        "bad; 3 an internal error (rerun with -v for the traceback); 130 interrupted.",
    )
    p.add_argument("log", type=input_file, help="the run log, e.g. out/sim/run.mcap")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a setting before replaying (repeatable): planner.FIELD=NUMBER (resolution_m, "
        "robot_radius_m, sonar_margin_m, ...; `rovernav plan --help` lists the planner), "
        "host_replan=true|false, strategy=rovernav|seed",
    )
    p.add_argument(
        "--json",
        type=output_file(".json"),
        metavar="FILE",
        help="also write the comparison as JSON: every path recorded and replayed, the first difference",
    )
    p.add_argument(
        "--plot",
        type=output_file(".png"),
        metavar="FILE",
        help="also draw the arena with the recorded paths and the replayed ones (PNG)",
    )
    p.add_argument("--quiet", action="store_true", help="print only the verdict line")
    p.set_defaults(func=cmd_replay)


def parse_settings(spec, settings: list[str]):
    """`spec` with --set's changes; InputError naming a bad one."""
    import dataclasses

    from ..errors import InputError

    planner: dict[str, float] = {}
    other: dict[str, object] = {}
    for item in settings:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value:
            raise InputError(f"--set {item!r}: expected KEY=VALUE, e.g. planner.robot_radius_m=0.14")
        if key.startswith("planner."):
            try:
                planner[key[len("planner.") :]] = float(value)
            except ValueError:
                raise InputError(f"--set {item!r}: {value!r} is not a number") from None
        elif key == "host_replan":
            if value.lower() not in ("true", "false"):
                raise InputError(f"--set {item!r}: host_replan is true or false")
            other[key] = value.lower() == "true"
        elif key == "strategy":
            from ..mission.strategies import STRATEGIES

            if value not in STRATEGIES:
                raise InputError(f"--set {item!r}: strategy is one of {', '.join(STRATEGIES)}")
            other[key] = value
        else:
            raise InputError(f"--set {item!r}: unknown setting {key!r} (planner.FIELD, host_replan, strategy)")
    if planner:
        try:
            spec = spec.with_planner(**planner)
        except (TypeError, ValueError) as exc:
            raise InputError(f"--set: {exc}") from None
    return dataclasses.replace(spec, **other) if other else spec


def cmd_replay(args: argparse.Namespace) -> int:
    from ..files import write_json_atomic
    from .replay import read_log, replay, replay_picture, report_text

    run = read_log(args.log)
    spec = parse_settings(run.spec, args.set)
    if not args.quiet:
        print(
            f"replaying {args.log}: a {run.source} run, {len(run.inputs):,} host inputs, {len(run.sent):,} frames sent",
            flush=True,
        )

    started = time.monotonic()

    def progress(t_s: float) -> None:  # only for a replay that takes a while (a long run's log)
        if not args.quiet and time.monotonic() - started > 2.0:
            print(f"  ... {t_s:6.1f} s of the mission replayed", file=sys.stderr, flush=True)

    result = replay(run, spec, progress=progress)
    text = report_text(result)
    verdict = next(line for line in text.splitlines() if line.startswith(("identical", "DIFFERENT")))
    print(verdict if args.quiet else text)
    if args.json:
        write_json_atomic(args.json, result.to_json())
    if args.plot:
        replay_picture(result, args.plot)
    if not args.quiet and (args.json or args.plot):
        print("wrote " + ", ".join(str(p) for p in (args.json, args.plot) if p))
    return 0 if result.identical else 1
