"""`rovernav locate IMAGE`: where are the rover and the target in this picture?

    rovernav locate frame.png [--config FILE] [--arena-size W H] [--json]

Exit status: 0 when the rover was found, 1 when it was not (the reason is printed), 2 when the
image or the config file cannot be used.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

EXIT_FOUND = 0
EXIT_NOT_FOUND = 1
EXIT_ERROR = 2


class _UsageError(Exception):
    """Something the user gave cannot be used; the message says what."""


def add_locate_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `locate` command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "locate", help="find the rover and the target in an overhead image",
        description="Find the rover (its pose: position in arena metres, heading in degrees, 0 = up the "
                    "image, clockwise) and the target (its position) in one overhead image, as the "
                    "mission's vision does for every camera frame.",
        epilog="Exit status: 0 rover found, 1 rover not found (the reason is printed), "
               "2 the image or config cannot be used.")
    p.add_argument("image", help="the image file (PNG, JPEG, ... anything OpenCV reads)")
    p.add_argument("--config", metavar="FILE",
                   help="rovernav TOML configuration: its [vision] table (markers, HSV ranges, ArUco ids, "
                        "calibration, ...) and [arena] width_m / height_m")
    p.add_argument("--arena-size", nargs=2, type=float, metavar=("W", "H"),
                   help="arena width and height in metres (default: the config's [arena], else 2.36 1.75)")
    p.add_argument("--json", action="store_true",
                   help='print {"rover": {"x_m", "y_m", "heading_deg"} | null, '
                        '"target": {"x_m", "y_m"} | null, "reason": str | null, "target_reason": str | null}')
    p.set_defaults(func=run_locate)
    return p


def run_locate(args: argparse.Namespace) -> int:
    """The `locate` command's handler; returns the exit status."""
    try:
        return _run(args)
    except _UsageError as exc:
        print(f"rovernav locate: {exc}", file=sys.stderr)
        return EXIT_ERROR


def _run(args: argparse.Namespace) -> int:
    import cv2

    from ..config import ConfigError, load_config
    from .locator import Locator

    try:
        cfg = load_config(args.config)
    except ConfigError as exc:
        raise _UsageError(str(exc)) from exc
    size = tuple(args.arena_size) if args.arena_size is not None else (cfg.arena.width_m, cfg.arena.height_m)
    if not Path(args.image).is_file():
        raise _UsageError(f"cannot read image {args.image!r}: no such file")
    frame = cv2.imread(args.image, cv2.IMREAD_COLOR)
    if frame is None:
        raise _UsageError(f"cannot read image {args.image!r}: not an image OpenCV can decode")
    try:
        locator = Locator(cfg.vision, *size)
    except ValueError as exc:
        raise _UsageError(str(exc)) from exc
    d = locator.locate(frame)

    if args.json:
        out = {
            "rover": None if d.rover is None else
            {"x_m": round(d.rover.x_m, 4), "y_m": round(d.rover.y_m, 4), "heading_deg": round(d.rover.heading_deg, 2)},
            "target": None if d.target is None else {"x_m": round(d.target.x_m, 4), "y_m": round(d.target.y_m, 4)},
            "reason": d.reason,
            "target_reason": d.target_reason,
        }
        print(json.dumps(out))
    else:
        if d.rover is not None:
            print(f"rover   x {d.rover.x_m:.3f} m  y {d.rover.y_m:.3f} m  heading {d.rover.heading_deg:.1f}°")
        else:
            print(f"rover   not found: {d.reason}")
        if d.target is not None:
            print(f"target  x {d.target.x_m:.3f} m  y {d.target.y_m:.3f} m")
        else:
            print(f"target  not found: {d.target_reason}")
    return EXIT_FOUND if d.rover is not None else EXIT_NOT_FOUND
