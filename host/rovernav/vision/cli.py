"""`rovernav locate IMAGE`: where the camera sees the rover and the target, to check a set-up."""
from __future__ import annotations

import argparse
import json
import sys


def add_locate_parser(sub) -> None:
    p = sub.add_parser(
        "locate", help="find the rover and the target in a camera image",
        description="Print the rover's pose and the target's position, in arena metres and degrees (0 = up the "
                    "image, clockwise), as the host's vision sees them in IMAGE. Use it to check a camera "
                    "set-up: lighting, HSV ranges, calibration. Exit status 0 when the rover was found, 1 when it "
                    "was not (the reason is printed), 2 for an unreadable image or configuration.")
    p.add_argument("image", help="a camera frame (PNG, JPEG, ...)")
    p.add_argument("--config", help="rovernav TOML configuration ([arena] size, [vision] markers and calibration)")
    p.add_argument("--arena-size", nargs=2, type=float, metavar=("W", "H"),
                   help="arena width and height in metres (default: the configuration's, else 2.36 1.75)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=cmd_locate)


def cmd_locate(args: argparse.Namespace) -> int:
    import cv2

    from ..config import ConfigError, load_config
    from .locator import Locator

    try:
        cfg = load_config(args.config)
    except ConfigError as exc:
        print(f"rovernav locate: {exc}", file=sys.stderr)
        return 2
    frame = cv2.imread(args.image, cv2.IMREAD_COLOR)
    if frame is None:
        print(f"rovernav locate: cannot read image {args.image!r} (missing, or not an image)", file=sys.stderr)
        return 2
    w, h = args.arena_size if args.arena_size else (cfg.arena.width_m, cfg.arena.height_m)
    det = Locator(cfg.vision, w, h).locate(frame)
    if args.json:
        out = {"rover": None if det.rover is None else
               {"x_m": round(det.rover[0], 4), "y_m": round(det.rover[1], 4), "heading_deg": round(det.rover[2], 2)},
               "target": None if det.target is None else {"x_m": round(det.target[0], 4), "y_m": round(det.target[1], 4)},
               "reason": det.reason}
        print(json.dumps(out))
    else:
        if det.rover is not None:
            print(f"rover:  x {det.rover[0]:.3f} m  y {det.rover[1]:.3f} m  heading {det.rover[2]:.1f} deg")
        else:
            print(f"rover:  not found: {det.reason}")
        print(f"target: x {det.target[0]:.3f} m  y {det.target[1]:.3f} m" if det.target else "target: not found")
    return 0 if det.rover is not None else 1
