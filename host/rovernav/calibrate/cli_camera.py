"""`rovernav calibrate camera` and `rovernav calibrate tags`: the commands themselves (their flags
are in calibrate/cli.py). The frames read from files or a live camera, the calibration run and
checked, the [vision] table printed or written into a configuration; the corner tags drawn."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import InputError
from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from ..vision import marks
from . import camera as cc

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg")


def cmd_tags(args) -> int:
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


def cmd_camera(args) -> int:
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
