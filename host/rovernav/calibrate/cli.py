"""`rovernav calibrate camera` (the camera's calibration from a still, a video or a live camera)
and `rovernav calibrate rover` (the motors' figures from runs the camera watches)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..errors import InputError
from ..link import messages_gen as mg
from ..validate import number, output_file
from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from ..vision import marks
from . import camera as cc

HELP = """\
Find where the arena lies in the camera's frame and the HSV ranges of the rover's and the
target's colour markers under this room's light, check them with the locator the mission uses,
and write the [vision] table of a configuration.

What the camera must see: the rover (its two colour squares uncovered) and the target marker on
the floor, and either the four corner tags (ArUco DICT_4X4_50 ids 10, 11, 12, 13 at the
bottom-left, bottom-right, top-right and top-left corners as the arena's x and y run, each
centred 0.07 m in from both walls; `rovernav calibrate tags DIR` draws them to print) or, without them, the arena's corners given with --corners. Give the stickers' colours
(--front orange --back green --target yellow, the seed's) when they are not the configuration's.

Several frames (of a video, or --frames from a live camera) make the ranges hold the noise and
flicker of the light; the rover need not move. A picture (--picture) shows the arena's grid, the
markers found and the pose: if the grid does not lie on the floor's edges, it is wrong."""

EPILOG = (
    "exit status: 0 calibrated and checked; 1 it could not be done (the reason, in one line: no arena, too dark, "
    "a marker cut by the frame's edge, no rover pair, a colour not seen); 2 unusable input (a flag, file or "
    "value, named in a one-line error); 3 an internal error (rerun with -v for the traceback); 130 interrupted."
)

ROVER_HELP = """\
Fit the rover's motor figures from three straight runs of 0.5 m the camera watches: ahead the
way the rover faces, back, and ahead again, at drive commands of 60, 80 and 105 PWM (sweeps
off). Stand the rover where the camera sees it, facing 0.8 m of open floor; calibrate the
camera first (rovernav calibrate camera). Power the rover up still (its gyro measures its bias
in its first second).

From each run's steady part: the speed the camera saw and the mean left and right commands
the rover reported. A line through (left command, speed) gives the speed per PWM and the
dead band where it meets zero; the commands that held the rover straight give how much
stronger the right motor is. Written as the rover's parameters speed_mm_s_per_pwm_x1000,
motor_deadband_pwm and right_bias_permille; printed with the configuration's values and how
well the line fits.

The gyro, measured and printed, not written (no parameter takes them): its scale (no fix is
sent while the rover turns round before a run, so its heading there is its gyro's alone,
against the camera's) and the bias its start-up measure left (the rover stands still for 8 s
before the first run, no fix sent: its heading's drift).

The sonar's offset (how far ahead of the rover's centre the ranger sits: [planner]
sonar_offset_m) needs a wall at a known place: give its face with --wall X0,Y0,X1,Y1 (arena
metres) and stand the rover facing it square, its ranger 0.15-0.5 m from it, 0.8 m of open floor
behind. The first and third runs then begin with a sweep, and the runs go away from the wall.
The simulator's bench (--sim) has such a wall."""

ROVER_EPILOG = (
    "exit status: 0 fitted (and written with --write); 1 the runs gave no fit (the reason, in one line: "
    "the rover did not drive, the camera lost it, the speeds do not rise with the command); 2 unusable "
    "input (a flag, file or value, named in a one-line error; no room ahead of the rover; the rover not "
    "facing the --wall near it); 3 an internal "
    "error (rerun with -v for the traceback); 130 interrupted."
)

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg")


def add_calibrate_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "calibrate",
        help="calibrate the camera (arena corners, marker colours) and the rover (motor figures) from what the camera sees",
        description="Calibrate the set-up from what the camera sees.",
        epilog=EPILOG,
    )
    sub = p.add_subparsers(dest="what", metavar="WHAT", parser_class=type(p))
    c = sub.add_parser(
        "camera",
        help="the arena's corners and the markers' HSV ranges, into [vision]",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=HELP,
        epilog=EPILOG,
    )
    c.add_argument(
        "source", nargs="*", metavar="SOURCE", help="image files (PNG, JPEG, ...) or one video file; none with --camera"
    )
    c.add_argument(
        "--camera",
        type=number(0, 63, integer=True),
        metavar="INDEX",
        help="a live camera, by its index (0 is the first), instead of files",
    )
    c.add_argument(
        "--frames",
        type=number(1, 100, integer=True),
        default=5,
        metavar="N",
        help="frames taken from a video or a live camera, 1 to 100 (default 5)",
    )
    c.add_argument(
        "--corners",
        nargs=4,
        metavar="U,V",
        help="the arena's corners in the frame, in pixels (bottom-left, bottom-right, top-right, top-left), "
        "instead of corner tags",
    )
    c.add_argument(
        "--arena-size",
        nargs=2,
        type=number(0.0, 100.0, lo_open=True),
        metavar=("W", "H"),
        help="arena width and height in metres (default: the configuration's [arena], else "
        f"{DEFAULT_ARENA_WIDTH_MM / 1000:g} {DEFAULT_ARENA_HEIGHT_MM / 1000:g})",
    )
    words = sorted(marks.COLOUR_BANDS)
    for flag, role in (("--front", "rover's front"), ("--back", "rover's back"), ("--target", "target")):
        c.add_argument(
            flag,
            choices=words,
            metavar="COLOUR",
            help=f"the {role} marker's colour ({', '.join(words)}); default: as the configuration's ranges say",
        )
    c.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="the configuration to start from (its [arena] and the rest of its [vision])",
    )
    c.add_argument(
        "--write",
        type=output_file(".toml"),
        metavar="FILE",
        help="write the result into FILE's [vision] table (made if missing; every other table and key "
        "kept); without it the table is printed",
    )
    c.add_argument(
        "--picture",
        type=output_file(".png", ".jpg"),
        default=Path("calibration-check.png"),
        metavar="FILE",
        help="the check picture (default calibration-check.png)",
    )
    c.add_argument("--json", action="store_true", help="print the result as one JSON object")
    c.set_defaults(func=_cmd_camera)
    r = sub.add_parser(
        "rover",
        help="the motors' dead band, speed per PWM and balance, from runs the camera watches",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=ROVER_HELP,
        epilog=ROVER_EPILOG,
    )
    where = r.add_mutually_exclusive_group()
    where.add_argument("--port", metavar="PORT", help="the rover's serial port (its radio), as for rovernav run")
    where.add_argument("--sim", action="store_true", help="calibrate the simulated rover instead")
    r.add_argument(
        "--camera",
        metavar="SOURCE",
        help="with --port: the camera (index or video/URL; default: the configuration's [camera] source)",
    )
    r.add_argument(
        "--setup",
        type=number(0, 2**31 - 1, integer=True),
        metavar="SEED",
        help="with --sim: a simulated set-up (marker colours, light, camera pose, plant) by its seed; "
        "give the --config its camera was calibrated into",
    )
    r.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="the configuration (its [vision], [link] and [rover]); default: the built-in one",
    )
    r.add_argument(
        "--write",
        type=output_file(".toml"),
        metavar="FILE",
        help="write the fitted parameters into FILE's [rover] table, and the sonar's offset into its "
        "[planner] (made if missing; every other table and key kept); without it they are printed",
    )
    r.add_argument(
        "--wall",
        type=wall_face,
        metavar="X0,Y0,X1,Y1",
        help="with --port: the face of a straight wall the rover stands facing (arena metres, its two "
        "ends), to measure the sonar's offset from",
    )
    r.add_argument("--json", action="store_true", help="print the result as one JSON object")
    r.set_defaults(func=_cmd_rover)
    t = sub.add_parser(
        "tags",
        help="draw the four corner tags to print",
        description="Write the four ArUco corner tags (DICT_4X4_50 ids 10-13) as PNG files to print "
        "at 300 dots per inch, each 10 cm across its black square with a white margin, "
        "named by the corner it goes to.",
        epilog="exit status: 0 written; 2 unusable input (the folder cannot be made or written); 3 an "
        "internal error (rerun with -v for the traceback); 130 interrupted.",
    )
    t.add_argument("out", type=Path, metavar="DIR", help="the folder to write them in (made if missing)")
    t.set_defaults(func=_cmd_tags)
    p.set_defaults(func=lambda args: _no_what(p))
    return p


def _cmd_tags(args) -> int:
    import cv2
    import numpy as np

    if args.out.exists() and not args.out.is_dir():
        raise InputError(f"{args.out}: exists and is not a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    dpi, side_m = 300, 0.10
    side_px = round(side_m / 0.0254 * dpi)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, marks.CORNER_DICTIONARY))
    for tag, name in zip(marks.CORNER_TAG_IDS, ("bottom-left", "bottom-right", "top-right", "top-left")):
        img = cv2.aruco.generateImageMarker(d, tag, side_px)
        margin = side_px // 6
        page = np.full((side_px + 2 * margin + 60, side_px + 2 * margin), 255, np.uint8)
        page[margin : margin + side_px, margin : margin + side_px] = img
        cv2.putText(
            page,
            f"rovernav corner tag {tag}: {name}, centre {marks.CORNER_INSET_M * 100:.0f} cm in from both walls",
            (margin, side_px + 2 * margin + 30),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.8,
            0,
            2,
        )
        path = args.out / f"corner-tag-{tag}-{name}.png"
        if not cv2.imwrite(str(path), page):
            raise InputError(f"{path}: could not be written")
        print(f"wrote {path}")
    print(f"print at {dpi} dpi (100 % scale): the black square must measure {side_m * 100:.0f} cm")
    return 0


def _no_what(p: argparse.ArgumentParser) -> int:
    p.print_help()
    return 2


def _corners(texts: list[str]) -> list[tuple[float, float]]:
    out = []
    for t in texts:
        try:
            u, v = (float(x) for x in t.split(","))
        except ValueError:
            raise InputError(f"--corners {t!r}: expected U,V in pixels, e.g. 102.5,411") from None
        if not all(abs(x) < 1e5 for x in (u, v)):
            raise InputError(f"--corners {t!r}: not a pixel position")
        out.append((u, v))
    return out


def read_frames(args) -> list:
    """The frames to calibrate from, or InputError naming the source."""
    import cv2

    from ..vision.cli import _UsageError, read_image

    try:  # OpenCV's own warnings (no device, a broken video) would add lines to a one-line error
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    except AttributeError:
        pass
    if args.camera is not None:
        if args.source:
            raise InputError("give files or --camera, not both")
        cap = cv2.VideoCapture(int(args.camera))
        if not cap.isOpened():
            raise InputError(f"--camera {args.camera}: no camera there (is it plugged in, or used by another program?)")
        frames = []
        try:
            for _ in range(10):  # let the exposure settle
                cap.read()
            while len(frames) < args.frames:
                ok, f = cap.read()
                if not ok:
                    raise InputError(f"--camera {args.camera}: it stopped giving frames after {len(frames)}")
                frames.append(f)
        finally:
            cap.release()
        return frames
    if not args.source:
        raise InputError("nothing to calibrate from: give image files, a video file, or --camera INDEX")
    videos = [s for s in args.source if Path(s).suffix.lower() in VIDEO_SUFFIXES]
    if videos:
        if len(args.source) > 1:
            raise InputError(f"{videos[0]}: give one video, or image files, not both")
        path = Path(videos[0])
        if path.is_dir():
            raise InputError(f"{videos[0]}: is a folder, not a video file")
        if not path.is_file():
            raise InputError(f"{videos[0]}: no such video file")
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise InputError(f"{videos[0]}: not a video OpenCV can open")
        total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        want = [round(i * (total - 1) / max(1, args.frames - 1)) for i in range(args.frames)] if total > 0 else None
        frames, k = [], 0
        try:
            while want is None or k <= want[-1]:
                if want is not None and k not in want:
                    if not cap.grab():  # skipped frames are not decoded
                        break
                else:
                    ok, f = cap.read()
                    if not ok:
                        break
                    frames.append(f)
                k += 1
                if want is None and len(frames) >= args.frames:
                    break
        finally:
            cap.release()
        if not frames:
            raise InputError(f"{videos[0]}: no frame could be read")
        if len(frames) < args.frames:
            print(
                f"{videos[0]}: {len(frames)} frames read of the {args.frames} asked (the video ends sooner than "
                "it says)",
                file=sys.stderr,
            )
        return frames
    frames = []
    for s in args.source:
        try:
            frames.append(read_image(s))
        except _UsageError as exc:
            raise InputError(str(exc)) from None
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise InputError("the images are not all the same size: frames of one camera, please")
    return frames


def _vision_toml(vision_dict: dict) -> str:
    import tomlkit

    doc = tomlkit.document()
    doc["vision"] = vision_dict
    return tomlkit.dumps(doc)


def write_vision(path: Path, vision_dict: dict, arena: tuple[float, float]) -> None:
    """Put `vision_dict`'s markers, hsv and calibration into FILE's [vision] (other keys kept), and
    [arena] when the file had none; checked as a configuration before it is written."""
    from .toml_update import load_for_update, table_for_update, write_checked

    doc = load_for_update(path, "rovernav configuration; [vision] written by `rovernav calibrate camera`")
    for name in ("arena", "vision"):
        if name in doc and not isinstance(doc[name], dict):
            raise InputError(f"{path}: [{name}] is not a table, so it cannot be updated")
    if "arena" not in doc:
        doc["arena"] = {"width_m": arena[0], "height_m": arena[1]}
    have = (
        doc["arena"].get("width_m", DEFAULT_ARENA_WIDTH_MM / 1000.0),
        doc["arena"].get("height_m", DEFAULT_ARENA_HEIGHT_MM / 1000.0),
    )
    if any(abs(float(a) - b) > 1e-3 for a, b in zip(have, arena)):
        raise InputError(
            f"{path}: its [arena] is {have[0]} x {have[1]} m, the calibration's {arena[0]:g} x "
            f"{arena[1]:g} m: give the same --arena-size, or change [arena] first"
        )
    vision = table_for_update(path, doc, "vision")
    for key in ("markers", "hsv", "calibration"):
        vision[key] = vision_dict[key]
    write_checked(path, doc)


def _cmd_camera(args) -> int:
    import cv2

    from ..config import load_config

    if args.config is not None and not args.config.is_file():
        raise InputError(f"{args.config}: no such configuration file")
    cfg = load_config(args.config)  # ConfigError (exit 2) names the file and key
    w, h = tuple(args.arena_size) if args.arena_size else (cfg.arena.width_m, cfg.arena.height_m)
    corners = _corners(args.corners) if args.corners else None
    if corners is None and min(w, h) < 2 * marks.CORNER_INSET_M + 0.1:
        raise InputError(
            f"a {w:g} x {h:g} m arena has no room for the corner tags ({marks.CORNER_INSET_M * 100:.0f} cm in "
            "from each wall): give its corners with --corners"
        )
    words = {
        role: getattr(args, flag)
        for role, flag in (("rover_front", "front"), ("rover_back", "back"), ("target", "target"))
        if getattr(args, flag)
    }
    frames = read_frames(args)
    print(
        f"calibrating from {len(frames)} frame{'s' if len(frames) > 1 else ''} of "
        f"{frames[0].shape[1]} x {frames[0].shape[0]} pixels ...",
        file=sys.stderr,
    )
    if corners is not None:
        try:
            corners = cc.check_corners(corners, frames[0].shape)
        except cc.CalibrationFailed as exc:
            raise InputError(f"--corners: {exc}") from None
    try:
        result = cc.calibrate_camera(frames, w, h, corners_px=corners, words=words or None, base=cfg.vision)
    except cc.CalibrationFailed as exc:
        print(f"rovernav calibrate camera: could not calibrate: {exc}", file=sys.stderr)
        return 1
    vision = result.vision(cfg.vision)
    table = vision.to_dict()
    if not cv2.imwrite(str(args.picture), cc.check_picture(frames[0], result)):
        raise InputError(f"--picture {args.picture}: could not be written")
    if args.write:
        write_vision(args.write, table, (w, h))
    pose = result.poses[0]
    if args.json:
        print(
            json.dumps(
                {
                    "arena": {
                        "how": result.how,
                        "corners_px": [list(c) for c in result.corners_px],
                        "width_m": w,
                        "height_m": h,
                    },
                    "hsv": {k: [list(lo), list(hi)] for k, (lo, hi) in result.hsv.items()},
                    "colours": result.colour_words(),
                    "frames": result.frames,
                    "found": result.found,
                    "rover": {
                        "x_m": round(pose.x_m, 4),
                        "y_m": round(pose.y_m, 4),
                        "heading_deg": round(pose.heading_deg, 2),
                    },
                    "picture": str(args.picture),
                    "written": str(args.write) if args.write else None,
                }
            )
        )
        return 0
    cal = result.calibration
    ppm = cal.pixels_per_metre(w / 2, h / 2)
    print(
        f"arena    {result.how}: {w:g} x {h:g} m, corners at "
        + ", ".join(f"({u:.1f}, {v:.1f})" for u, v in result.corners_px)
        + f" px; {ppm:.0f} px/m at its centre"
    )
    names = {"rover_front": "rover front", "rover_back": "rover back", "target": "target"}
    for role, (lo, hi) in result.hsv.items():
        print(
            f"marker   {names[role]:<11} {result.colour_words()[role]:<8} H {lo[0]}-{hi[0]}, S >= {lo[1]}, V >= {lo[2]}"
        )
    print(
        f"check    the locator with these finds the rover in {result.found}/{result.frames} frames: "
        f"({pose.x_m:.3f}, {pose.y_m:.3f}) m, heading {(pose.heading_deg + 0.05) % 360 - 0.05:.1f} deg"
    )
    print(f"picture  {args.picture} (the grid must lie on the floor, the arrow along the rover)")
    if args.write:
        print(f"wrote    [vision] markers, hsv and calibration of {args.write}")
    else:
        print("\n# the [vision] table for your configuration (or run again with --write FILE):")
        print(_vision_toml({k: table[k] for k in ("markers", "hsv", "calibration")}), end="")
    return 0


def wall_face(text: str) -> tuple[float, float, float, float]:
    """--wall's X0,Y0,X1,Y1: four finite numbers [m], the ends at least 0.2 m apart."""
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: give the wall's face as X0,Y0,X1,Y1, four numbers in metres")
    if math.hypot(values[2] - values[0], values[3] - values[1]) < 0.2:
        raise argparse.ArgumentTypeError(f"{text!r}: the wall's ends are less than 0.2 m apart")
    return values


def _cmd_rover(args) -> int:
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
