"""The `rovernav` command.

    rovernav sim [SCENARIO]               a whole mission in the simulator (the main job)
    rovernav replay LOG.mcap              the host's mission code again against a recorded run
    rovernav run --port P --camera C      a mission with a real rover and webcam
    rovernav plan SCENARIO                plan a path on a scenario's arena
    rovernav locate IMAGE                 find the rover and the target in a camera image
    rovernav pose / rovernav study        the Russo (2024) study: moving to a pose, A* on a crater map, EKF
    rovernav protocol [--json]            the link protocol's messages and parameters
    rovernav link-check --port PORT       say HELLO to a rover and watch what it sends
    rovernav link-check --port P --soak S measure the radio: frames lost, round trip, path load time
    rovernav demo                         the Uno firmware in an AVR simulator, talking to the host

Errors a user can cause (a bad flag or file, a missing port, a rover built from another
protocol, no answer) end with a one-line message and exit status 2, not a traceback; a mission
that could not reach its goal ends with exit status 1; an internal error with 3 (see
rovernav.validate, which every entry point checks its input with).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

from . import __version__
from .validate import (
    EXIT_CODES,
    MAX_SIM_TIME_S,
    ArgParser,
    input_file,
    number,
    output_file,
    port_spec,
    seconds,
    show,
)
from .vehicle_gen import LINK_BAUD

log = logging.getLogger("rovernav")


def _cmd_protocol(args: argparse.Namespace) -> int:
    from .link import framing
    from .link import messages_gen as mg

    if args.json:
        out = {
            "schema_hash": f"0x{mg.SCHEMA_HASH:08X}",
            "protocol_version": mg.PROTOCOL_VERSION,
            "max_frame_bytes": framing.MAX_FRAME,
            "messages": [
                {
                    "name": cls.NAME,
                    "id": cls.ID,
                    "direction": cls.DIRECTION,
                    "payload_bytes": cls.STRUCT.size,
                    "fields": [{"name": f.name, "type": f.type, "count": f.count, "unit": f.unit} for f in cls.FIELDS],
                }
                for cls in mg.MESSAGES.values()
            ],
            "params": [
                {"id": p.id, "name": p.name, "unit": p.unit, "default": p.default, "min": p.min, "max": p.max}
                for p in mg.PARAMS.values()
            ],
        }
        print(json.dumps(out, indent=2))
        return 0
    print(
        f"rovernav link protocol v{mg.PROTOCOL_VERSION}, schema hash 0x{mg.SCHEMA_HASH:08X}, "
        f"frames up to {framing.MAX_FRAME} bytes on the wire (COBS, CRC-16/CCITT-FALSE)\n"
    )
    print(f"{'id':>4}  {'message':<10} {'direction':<14} {'bytes':>5}  fields")
    for cls in mg.MESSAGES.values():
        fields = ", ".join(f"{f.name}[{f.count}]" if f.count else f.name for f in cls.FIELDS)
        print(f"0x{cls.ID:02X}  {cls.NAME:<10} {cls.DIRECTION:<14} {len(framing.encode_frame(cls(), 0)):>5}  {fields}")
    print(f"\n{'id':>4}  {'parameter (CONFIG)':<26} {'default':>8}  {'range':<18} unit")
    for p in mg.PARAMS.values():
        print(f"{p.id:>4}  {p.name:<26} {p.default:>8}  [{p.min}, {p.max}]".ljust(62) + f" {p.unit}")
    return 0


def _cmd_link_check(args: argparse.Namespace) -> int:
    from .link.check import talk_to_rover
    from .link.keys import load_key_file
    from .link.link import Link
    from .link.transport import open_transport

    if args.json is not None and args.soak is None:
        print("rovernav link-check: --json writes a soak's figures: give --soak SECONDS too", file=sys.stderr)
        return 2
    if args.soak is not None and args.seconds is not None:
        print(
            "rovernav link-check: --seconds is how long to listen without a soak; with --soak give one of them",
            file=sys.stderr,
        )
        return 2
    key = load_key_file(args.key_file) if args.key_file else None
    with open_transport(args.port) as transport:
        if args.soak is not None:
            from .link.soak import soak_rover

            return soak_rover(Link(transport, key=key), args.soak, args.timeout, args.json)
        talk_to_rover(Link(transport, key=key), 3.0 if args.seconds is None else args.seconds, args.timeout)
    return 0


def _cmd_keygen(args: argparse.Namespace) -> int:
    from .link.keys import write_key_file

    write_key_file(args.out, force=args.force)
    print(
        f"wrote a new 128-bit link key to {args.out} (mode 0600); keep it secret, and give the same file "
        "to the host that commands this rover ([link] key_file in its configuration)"
    )
    return 0


def _fleet_id(text: str) -> int:
    """An argparse type: a fleet id, 0 (a lone rover) or 1..MAX_ROVERS."""
    from .link.messages_gen import MAX_ROVERS
    from .link.provision import check_fleet_id

    try:
        return check_fleet_id(int(text))
    except ValueError:  # InputError is one
        raise argparse.ArgumentTypeError(
            f"{show(text)}: a fleet id is 0 (a lone rover) or 1..{MAX_ROVERS} (rover K of a fleet)"
        ) from None


def _cmd_provision(args: argparse.Namespace) -> int:
    from .link.keys import load_key_file
    from .link.provision import ProvisionError, provision
    from .link.transport import open_transport

    key = None if args.erase else load_key_file(args.key_file)
    current_key = load_key_file(args.current_key_file) if args.current_key_file else None
    transport = open_transport(args.port)
    try:
        print(f"opened {args.port}: waiting up to {args.boot_wait:g} s for the rover to boot ...")
        print(provision(transport, key, boot_wait_s=args.boot_wait, current_key=current_key, fleet_id=args.fleet_id))
    except ProvisionError as exc:
        print(f"rovernav provision: {exc}", file=sys.stderr)
        return exc.exit_code
    finally:
        transport.close()
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    return run_demo(seconds=args.seconds)


def _cmd_run(args: argparse.Namespace) -> int:
    from .errors import InputError
    from .hardware import default_log_path, run_hardware
    from .runlog.cli import live_port_of

    log_path = None if args.no_log else (args.log or default_log_path())
    if args.rovers is not None:
        from .fleet.run import run_fleet_hardware

        for flag, given in (("--map", args.map), ("--live", args.live)):
            if given:
                raise InputError(f"{flag} is for one rover; a fleet (--rovers {args.rovers}) runs without it")
        return run_fleet_hardware(
            args.rovers,
            args.port,
            args.camera,
            args.config,
            args.scenario,
            key_files=args.key_files,
            max_time_s=args.max_time,
            rover_configs=args.rover_configs,
            log_path=log_path,
            log_image_hz=args.log_image_hz,
            trips=args.trips,
        )
    for flag, given, one in (
        ("--key-files", args.key_files, "one rover's key is [link] key_file"),
        ("--rover-configs", args.rover_configs, "one rover's parameters are --config's [rover]"),
        ("--trips", args.trips, "one rover's trips are [mission] trips"),
    ):
        if given:
            raise InputError(f"{flag} is for a fleet (--rovers N); {one}")
    return run_hardware(
        args.port,
        args.camera,
        args.config,
        args.scenario,
        args.map,
        max_time_s=args.max_time,
        log_path=log_path,
        live_port=live_port_of(args),
        log_image_hz=args.log_image_hz,
    )


def _cmd_check(args: argparse.Namespace) -> int:
    from . import check
    from .errors import InputError

    if args.sim:
        if args.port or args.camera:
            raise InputError("--sim checks the simulated rover: give --port and --camera, or --sim, not both")
        from .config import load_config

        cfg = load_config(args.config)
        if args.setup is not None and args.config is None:
            print(
                "rovernav check: --setup without --config: the default configuration does not see that set-up's "
                "markers (calibrate: rovernav sim --setup SEED --calibration-frames DIR)",
                file=sys.stderr,
            )
        lines, elapsed = check.check_sim(cfg, fault=args.fault, setup_seed=args.setup)
    else:
        if args.fault or args.setup is not None:
            raise InputError("--fault and --setup are for --sim")
        if not args.port:
            raise InputError("give --port PORT (and --camera SOURCE) for the real rover, or --sim")
        lines, elapsed = check.check_hardware(args.port, args.camera, args.config)
    failed = not check.passed(lines)
    if args.json:
        print(
            json.dumps(
                {
                    "passed": not failed,
                    "elapsed_s": round(elapsed, 1),
                    "checks": [{"name": ln.name, "status": ln.status, "text": ln.text} for ln in lines],
                }
            )
        )
    else:
        for line in lines:
            print(line)
        print(check.summary_line(lines) + f" ({elapsed:.0f} s)")
    return 1 if failed else 0


def add_check_parser(sub) -> None:
    from . import check

    p = sub.add_parser(
        "check",
        help="pre-flight check: link, camera, gyro, sonar, servo, motors, one line each",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=check.__doc__,
        epilog="exit status: 0 every check passed; 1 a check failed or could not be made (its line "
        "says what to do); 2 "
        "unusable input (a flag, file or port, named in a one-line error); 3 an internal error "
        "(rerun with -v for the traceback); 130 interrupted.",
    )
    p.add_argument("--port", type=port_spec, help="the rover's serial port (its radio or USB cable)")
    p.add_argument(
        "--camera", help="the overhead camera: an index such as 0, or a video file (default: [camera] source)"
    )
    p.add_argument("--config", help="the configuration (calibrated [vision], [link] key_file, [rover] parameters)")
    p.add_argument(
        "--sim",
        action="store_true",
        help="check the simulated rover instead (the firmware core, a plant, a rendered camera)",
    )
    p.add_argument(
        "--setup",
        type=number(0, 2**32 - 1, integer=True),
        metavar="SEED",
        help="with --sim: a set-up that is not the defaults (rovernav sim --setup)",
    )
    p.add_argument("--fault", choices=check.FAULTS, help="with --sim: one fault for the check to find")
    p.add_argument("--json", action="store_true", help="print the lines as one JSON object")
    p.set_defaults(func=_cmd_check)


def add_run_parser(sub) -> None:
    p = sub.add_parser(
        "run",
        help="run a mission with a real rover and webcam",
        description="Run a mission against a real rover on PORT and an overhead camera SOURCE: "
        "the same host code as the simulator. Without --scenario the target is the "
        "yellow marker in view and the map starts empty. Ctrl-C stops the rover.",
    )
    p.add_argument("--port", default="", help="serial port of the radio, e.g. /dev/ttyUSB0 or COM4 (or [link] port)")
    p.add_argument("--camera", default="", help="camera index (0) or a video file (or [camera] source)")
    p.add_argument("--config", type=input_file, help="rovernav TOML configuration")
    p.add_argument("--scenario", help="scenario file: arena, start, target, known obstacles")
    p.add_argument("--map", help="learned map (JSON) to load at the start and save at the end")
    p.add_argument(
        "--max-time",
        type=seconds(MAX_SIM_TIME_S, positive=True),
        default=1800.0,
        metavar="S",
        help="stop the rover and end the mission after S seconds (default 1800)",
    )
    p.add_argument(
        "--log",
        type=output_file(".mcap"),
        metavar="FILE",
        help="the run log to write (default run-YYYYMMDD-HHMMSS.mcap in this folder)",
    )
    from .link.messages_gen import MAX_ROVERS

    p.add_argument(
        "--rovers",
        type=number(2, MAX_ROVERS, integer=True),
        default=None,
        metavar="N",
        help=f"a fleet of N rovers, 2 to {MAX_ROVERS}, under this one camera on this one radio (as `rovernav sim "
        "SCENARIO --rovers N`): needs --scenario, whose k-th start and site are rover k's berth and "
        "site; rover k is the one provisioned with --fleet-id k and carries ArUco tag 1, 3, 4 or 5 "
        "(rover 1, 2, 3, 4, with the default [vision.aruco] ids). The log has a channel set per rover",
    )
    p.add_argument(
        "--key-files",
        type=input_file,
        nargs="+",
        metavar="FILE",
        help="with --rovers: each rover's key file, rover 1's first (none: unsigned rovers)",
    )
    p.add_argument(
        "--rover-configs",
        type=input_file,
        nargs="+",
        metavar="FILE",
        help="with --rovers: each rover's own configuration file, rover 1's first, as `rovernav calibrate rover "
        "--write FILE` wrote it for that rover: its [rover] parameters (its motors' speed, dead band and "
        "balance) over --config's. The rest is the fleet's: the air's and the planner's parameters (refused "
        "in a rover's [rover]), and the sonar's offset (a rover's [planner] sonar_offset_m more than 5 mm "
        "from --config's is refused)",
    )
    p.add_argument(
        "--trips",
        type=number(1, 100, integer=True),
        default=None,
        help="with --rovers: round trips each rover makes (default: the scenario's [mission] trips)",
    )
    from .runlog.cli import add_log_flags

    add_log_flags(p, "--log")
    p.set_defaults(func=_cmd_run)


def build_parser() -> argparse.ArgumentParser:
    parser = ArgParser(
        prog="rovernav",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Guide a small rover through a partially unknown arena from an overhead camera. "
        "The rover (Arduino Uno firmware) follows waypoints on its own; this host sends it "
        "camera fixes and global paths over a framed, CRC-checked serial link.",
        epilog="Run `rovernav COMMAND --help` for a command's options.\n\n" + EXIT_CODES,
    )
    parser.add_argument("--version", action="version", version=f"rovernav {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log what the link does")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgParser)

    p = sub.add_parser(
        "protocol",
        help="list the link protocol's messages and parameters",
        description="Print every message (id, direction, size on the wire, fields) and every "
        "CONFIG parameter (default, range, unit) of protocol/messages.toml.",
    )
    p.add_argument("--json", action="store_true", help="print a JSON object instead of tables")
    p.set_defaults(func=_cmd_protocol)

    from .calibrate.cli import add_calibrate_parser
    from .evaluation.arenas import add_arenas_parser
    from .evaluation.trials import add_trials_parser
    from .planning.cli import add_plan_parser
    from .runlog.cli import add_replay_parser
    from .sim.cli import add_sim_parser
    from .study.cli import add_pose_parser, add_study_parser
    from .vision.cli import add_locate_parser

    add_sim_parser(sub)
    add_replay_parser(sub)
    add_arenas_parser(sub)
    add_trials_parser(sub)
    add_plan_parser(sub)
    add_locate_parser(sub)
    add_calibrate_parser(sub)
    add_run_parser(sub)
    add_check_parser(sub)
    add_pose_parser(sub)
    add_study_parser(sub)

    from .link import soak as sk

    p = sub.add_parser(
        "link-check",
        help="say HELLO to a rover and show what it sends, or soak the radio",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=sk.wrap(
            f"Open PORT at {LINK_BAUD:,} baud, exchange HELLO with the rover (checking that "
            "both were built from the same protocol definition), then print every "
            "message the rover sends for a few seconds, and the link's error "
            "counters."
        )
        + "\n\n"
        + sk.help_text(),
    )
    p.add_argument(
        "--port",
        required=True,
        type=port_spec,
        help=f"serial port of the radio or USB cable, e.g. /dev/ttyUSB0, COM4, or /dev/ttyUSB0@{LINK_BAUD}",
    )
    p.add_argument(
        "--seconds",
        type=seconds(3600.0),
        default=None,
        help="how long to listen after the HELLO, 0 to 3600 (default 3)",
    )
    p.add_argument(
        "--soak",
        type=number(sk.MIN_SOAK_S, sk.MAX_SOAK_S),
        metavar="SECONDS",
        help=f"measure the radio for SECONDS ({sk.MIN_SOAK_S:g} to {sk.MAX_SOAK_S:,.0f}) instead of "
        "listening: frame loss both ways, round trip, path load time, advice (see above)",
    )
    p.add_argument(
        "--json",
        type=output_file(".json"),
        metavar="FILE",
        help="with --soak: write the soak's figures to FILE (.json)",
    )
    p.add_argument(
        "--timeout",
        type=seconds(600.0, positive=True),
        default=3.0,
        help="how long to wait for the rover's HELLO, up to 600 s (default 3 s)",
    )
    p.add_argument(
        "--key-file",
        type=input_file,
        metavar="FILE",
        help="the link key of a rover that holds one (`rovernav keygen`, `rovernav provision`): "
        "frames are then signed and checked",
    )
    p.set_defaults(func=_cmd_link_check)

    p = sub.add_parser(
        "keygen",
        help="make a new key for signed frames",
        description="Write a new random 128-bit key for the link's signed frames (SipHash-2-4 "
        "tags, protocol/messages.toml [signing]) to FILE, readable by its owner only "
        "(mode 0600). An existing file is not replaced unless --force is given. "
        "Store it on the rover with `rovernav provision`, and give the host the same "
        "file ([link] key_file).",
    )
    p.add_argument(
        "--out",
        type=output_file(".key"),
        default="link.key",
        metavar="FILE",
        help="the key file to write, ending in .key (default link.key)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing key file")
    p.set_defaults(func=_cmd_keygen)

    from .link.messages_gen import MAX_ROVERS, SIGN_CONSENT_PIN

    pin = f"D{SIGN_CONSENT_PIN}"
    p = sub.add_parser(
        "provision",
        help="store the link key on the rover, over its USB cable",
        description="Open PORT (the Uno's USB cable: opening it resets the board), wait for the "
        "rover to boot, and send it the key in FILE (PROVISION, protocol/messages.toml). "
        "The rover stores it in EEPROM and from then on takes only frames signed with "
        "it. A rover with no key takes one only within 5 s of a reset, so a radio, "
        "which cannot reset it, cannot give it one: over a port that does not reset the "
        "rover nothing is sent. A rover that holds a key changes it, or erases it, only "
        "with its owner's consent: the command signed with the key it holds "
        f"(--current-key-file), or pin {pin} held to GND while it resets (a jumper from "
        f"{pin} to GND while this opens the port; take it off afterwards). Without "
        "either it refuses (exit 2). The rover's answer comes signed with the new key, "
        "which confirms it.",
    )
    p.add_argument(
        "--port",
        required=True,
        type=port_spec,
        help="the rover's USB serial port, e.g. /dev/ttyACM0 or COM3 (or PORT@BAUD)",
    )
    key_or_erase = p.add_mutually_exclusive_group(required=True)
    key_or_erase.add_argument(
        "--key-file", type=input_file, metavar="FILE", help="the key file `rovernav keygen` wrote"
    )
    key_or_erase.add_argument(
        "--erase", action="store_true", help="forget the rover's key: it takes unsigned commands again"
    )
    p.add_argument(
        "--current-key-file",
        type=input_file,
        metavar="FILE",
        help="the key file of the key the rover holds now: the new key (or --erase) is sent signed "
        "with it, the owner's consent a rover with a key needs (else: pin "
        f"{pin} held to GND at its reset). Checked against the rover's boot HELLO before "
        "anything is sent; a rover with no key does not need it",
    )
    p.add_argument(
        "--boot-wait",
        type=seconds(60.0, positive=True),
        default=4.0,
        metavar="S",
        help="how long to wait for the rover's boot HELLO after opening the port, up to 60 s (default 4)",
    )
    p.add_argument(
        "--fleet-id",
        type=_fleet_id,
        default=0,
        metavar="K",
        help=f"0 (the default): a lone rover, which talks freely; 1..{MAX_ROVERS}: rover K of a fleet sharing "
        "one radio, at address K - 1, which speaks only when spoken to ([fleet] of protocol/messages.toml). "
        "Stored with the key (also with --erase)",
    )
    p.set_defaults(func=_cmd_provision)

    p = sub.add_parser(
        "demo",
        help="run the Uno firmware in an AVR simulator and talk to it",
        description="Build the Uno image with Debian's avr-gcc, boot it in simavr with its serial "
        "port on a pseudo-terminal, and run link-check against it: the host and the "
        "very firmware the Uno runs, with no hardware.",
    )
    p.add_argument(
        "--seconds", type=seconds(3600.0), default=3.0, help="how long to listen after the HELLO, 0 to 3600 (default 3)"
    )
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s"
    )
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    from .errors import MissionFailed, RovernavError
    from .validate import internal_error

    if getattr(args, "what", None):  # a command with its own sub-commands: `rovernav calibrate camera`
        args.command = f"{args.command} {args.what}"
    try:
        return args.func(args)
    except MissionFailed as exc:
        print(f"rovernav {args.command}: {exc}", file=sys.stderr)
        return 1
    except RovernavError as exc:
        print(f"rovernav {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rovernav {args.command}: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print(
            f"rovernav {args.command}: out of memory: the input asks for more than this machine has "
            "(a smaller arena, a coarser resolution or a shorter run)",
            file=sys.stderr,
        )
        return 2
    except OSError as exc:  # a file or device the user named (the message names it)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"rovernav {args.command}: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the last line of defence: one line, not a traceback
        return internal_error(args.command, exc, args.verbose)


if __name__ == "__main__":
    sys.exit(main())
