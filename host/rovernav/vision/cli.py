"""`rovernav locate IMAGE`: where are the rover and the target in this picture?

    rovernav locate frame.png [--config FILE] [--arena-size W H] [--json]

Exit status: 0 when the rover was found, 1 when it was not (the reason is printed), 2 when the
image or the config file cannot be used.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import warnings
from pathlib import Path

from ..validate import MAX_ARENA_M, check_number, number
from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM

EXIT_FOUND = 0
EXIT_NOT_FOUND = 1
EXIT_ERROR = 2

# The images `locate` takes: big enough to find markers in (and for the colour search's
# downscale, up to 15, to leave pixels), small enough to decode and search in a few seconds
# and a few hundred MB (a 25-megapixel BGR frame is 75 MB; a camera frame is 0.3 to 2 MP).
MIN_IMAGE_SIDE_PX = 32
MAX_IMAGE_PIXELS = 25_000_000


class _UsageError(Exception):
    """Something the user gave cannot be used; the message says what."""


def add_locate_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `locate` command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "locate",
        help="find the rover and the target in an overhead image",
        description="Find the rover (its pose: position in arena metres, heading in degrees, 0 = up the "
        "image, clockwise) and the target (its position) in one overhead image, as the "
        "mission's vision does for every camera frame.",
        epilog="exit status: 0 the rover was found; 1 it was not (the reason is printed); 2 the image, the "
        "config or a flag cannot be used (a one-line error names it); 3 an internal error (rerun with "
        "-v for the traceback); 130 interrupted.",
    )
    p.add_argument(
        "image",
        help=f"the image file (PNG, JPEG, ... anything OpenCV reads), at least "
        f"{MIN_IMAGE_SIDE_PX} x {MIN_IMAGE_SIDE_PX} pixels and at most "
        f"{MAX_IMAGE_PIXELS / 1e6:g} megapixels",
    )
    p.add_argument(
        "--config",
        metavar="FILE",
        help="rovernav TOML configuration (a UTF-8 text file): its [vision] table (markers, HSV "
        "ranges, ArUco ids, calibration, ...) and [arena] width_m / height_m",
    )
    p.add_argument(
        "--arena-size",
        nargs=2,
        type=number(0.0, MAX_ARENA_M, lo_open=True),
        metavar=("W", "H"),
        help=f"arena width and height in metres, each > 0 and <= {MAX_ARENA_M:g} (default: the "
        f"config's [arena], else {DEFAULT_ARENA_WIDTH_MM / 1000:g} {DEFAULT_ARENA_HEIGHT_MM / 1000:g})",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help='print {"rover": {"x_m", "y_m", "heading_deg"} | null, '
        '"target": {"x_m", "y_m"} | null, "reason": str | null, "target_reason": str | null} '
        "(strict JSON: null, never NaN)",
    )
    p.set_defaults(func=run_locate)
    return p


def run_locate(args: argparse.Namespace) -> int:
    """The `locate` command's handler; returns the exit status."""
    try:
        return _run(args)
    except _UsageError as exc:
        print(f"rovernav locate: {exc}", file=sys.stderr)
        return EXIT_ERROR


def _finite(value: float, digits: int) -> float | None:
    """`value` rounded, or None when it is not a finite number (strict JSON has no NaN)."""
    value = float(value)
    return round(value, digits) if math.isfinite(value) else None


def _check_file(path_text: str, what: str) -> Path:
    """The path of an existing regular file, or _UsageError naming it."""
    if not path_text.strip():
        raise _UsageError(f"cannot read {what} {path_text!r}: an empty file name")
    path = Path(path_text)
    try:
        if not path.exists():
            raise _UsageError(f"cannot read {what} {path_text!r}: no such file")
        if path.is_dir():
            raise _UsageError(f"cannot read {what} {path_text!r}: is a folder, not a file")
        if not path.is_file():
            raise _UsageError(f"cannot read {what} {path_text!r}: not a regular file")
        if not os.access(path, os.R_OK):
            raise _UsageError(f"cannot read {what} {path_text!r}: permission denied")
    except OSError as exc:  # a name too long, a loop of links, ...
        raise _UsageError(f"cannot read {what} {path_text!r}: {exc.strerror or exc}") from None
    return path


def _header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from the image's header, without decoding it, when Pillow knows the format;
    None when it does not (OpenCV decodes it and the size is checked after)."""
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - matplotlib brings Pillow
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # DecompressionBombWarning: we judge the size ourselves
            with Image.open(path) as im:
                return im.size
    except Image.DecompressionBombError as exc:  # far beyond MAX_IMAGE_PIXELS
        import re

        found = re.search(r"\((\d+) pixels\)", str(exc))
        pixels = f"{int(found.group(1)):,} pixels" if found else "too many pixels"
        raise _UsageError(
            f"image {str(path)!r} is {pixels} by its header: more than the "
            f"{MAX_IMAGE_PIXELS / 1e6:g} megapixels locate takes"
        ) from None
    except Exception:  # noqa: BLE001 - not a format Pillow knows, or a broken header: OpenCV decides
        return None


def _check_size(image: str, width: int, height: int) -> None:
    if width < MIN_IMAGE_SIDE_PX or height < MIN_IMAGE_SIDE_PX:
        raise _UsageError(
            f"image {image!r} is {width} x {height} pixels: too small to find markers in "
            f"(at least {MIN_IMAGE_SIDE_PX} x {MIN_IMAGE_SIDE_PX})"
        )
    if width * height > MAX_IMAGE_PIXELS:
        raise _UsageError(
            f"image {image!r} is {width} x {height} pixels ({width * height / 1e6:.1f} megapixels): "
            f"more than the {MAX_IMAGE_PIXELS / 1e6:g} megapixels locate takes"
        )


def read_image(image: str):
    """The image as a BGR uint8 array, or _UsageError naming the file: missing, a folder, not an
    image OpenCV decodes, smaller than MIN_IMAGE_SIDE_PX or bigger than MAX_IMAGE_PIXELS (judged
    from the header, before decoding, for the formats Pillow knows)."""
    import cv2

    path = _check_file(image, "image")
    size = _header_size(path)
    if size is not None:
        _check_size(image, *size)
    try:
        frame = cv2.imread(str(path), cv2.IMREAD_COLOR)
    except cv2.error as exc:  # pragma: no cover - imread reports failures as None
        raise _UsageError(f"cannot read image {image!r}: OpenCV: {str(exc).strip().splitlines()[-1]}") from None
    if frame is None or frame.ndim != 3 or frame.shape[2] != 3 or frame.size == 0:
        raise _UsageError(f"cannot read image {image!r}: not an image OpenCV can decode")
    _check_size(image, frame.shape[1], frame.shape[0])
    return frame


def _run(args: argparse.Namespace) -> int:
    from ..config import ConfigError, load_config
    from .locator import Locator

    if args.config is not None:
        _check_file(args.config, "configuration file")
    try:
        cfg = load_config(args.config)
    except (ConfigError, ValueError) as exc:  # ValueError: a decoding error of an older load_config
        raise _UsageError(f"{args.config}: {exc}" if args.config and args.config not in str(exc) else str(exc)) from exc
    except OSError as exc:
        raise _UsageError(f"cannot read configuration file {args.config!r}: {exc.strerror or exc}") from exc
    try:
        if args.arena_size is not None:
            w = check_number("--arena-size W (m)", args.arena_size[0], 0.0, MAX_ARENA_M, lo_open=True)
            h = check_number("--arena-size H (m)", args.arena_size[1], 0.0, MAX_ARENA_M, lo_open=True)
        else:
            where = f"{args.config}: " if args.config else ""
            w = check_number(f"{where}[arena] width_m", cfg.arena.width_m, 0.0, MAX_ARENA_M, lo_open=True)
            h = check_number(f"{where}[arena] height_m", cfg.arena.height_m, 0.0, MAX_ARENA_M, lo_open=True)
    except ValueError as exc:
        raise _UsageError(str(exc)) from None
    frame = read_image(args.image)
    try:
        locator = Locator(cfg.vision, w, h)
    except ValueError as exc:
        raise _UsageError(str(exc)) from exc
    d = locator.locate(frame)

    if args.json:
        out = {
            "rover": None
            if d.rover is None
            else {
                "x_m": _finite(d.rover.x_m, 4),
                "y_m": _finite(d.rover.y_m, 4),
                "heading_deg": _finite(d.rover.heading_deg, 2),
            },
            "target": None if d.target is None else {"x_m": _finite(d.target.x_m, 4), "y_m": _finite(d.target.y_m, 4)},
            "reason": d.reason,
            "target_reason": d.target_reason,
        }
        print(json.dumps(out, allow_nan=False))
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
