"""`rovernav calibrate camera` (the camera's calibration from a still, a video or a live camera)
and `rovernav calibrate rover` (the motors' figures from runs the camera watches): their parsers
and help. The commands are in cli_camera.py (camera, tags) and cli_rover.py (rover)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..validate import number, output_file
from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from ..vision import marks
from .cli_camera import VIDEO_SUFFIXES, cmd_camera, cmd_tags, read_frames, write_vision
from .cli_rover import cmd_rover

__all__ = [
    "EPILOG",
    "HELP",
    "ROVER_EPILOG",
    "ROVER_HELP",
    "VIDEO_SUFFIXES",
    "add_calibrate_parser",
    "read_frames",
    "wall_face",
    "write_vision",
]

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
    c.set_defaults(func=cmd_camera)
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
    r.set_defaults(func=cmd_rover)
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
    t.set_defaults(func=cmd_tags)
    p.set_defaults(func=lambda args: _no_what(p))
    return p


def _no_what(p: argparse.ArgumentParser) -> int:
    p.print_help()
    return 2


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
