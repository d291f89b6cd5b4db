"""Vision settings: which markers to look for, how to clean the masks, what is plausible.

`VisionConfig` is frozen; build it in code or from the `[vision]` table of a TOML file with
`VisionConfig.from_dict`, which raises `ValueError` naming the bad key and value:

    [vision]
    markers = "colour"                  # "colour" (the seed's squares) or "aruco"
    downscale = 2                       # threshold on a copy this many times smaller (1 = full size)
    open_kernel_px = 3                  # morphological opening, at the downscaled size
    close_kernel_px = 3                 # morphological closing, at the downscaled size
    min_blob_area_px = 40               # full-size pixels; smaller blobs are noise
    doubled_area_ratio = 0.4            # a second blob at least this fraction of the largest: ambiguous
    rover_centre_fraction = 0.92        # rover centre = back + 0.92 * (front - back)
    marker_distance_m = 0.09            # expected distance between the front and back markers
    marker_distance_tolerance_m = 0.03
    max_rover_speed_m_s = 0.5           # a fix further than this speed allows from the last one is refused
    jump_slack_m = 0.03                 # measurement noise allowed on top of the speed limit

    [vision.hsv]                        # OpenCV units: H 0-179, S and V 0-255 (seed, Table 4.1)
    target = [[25, 40, 50], [35, 255, 255]]
    rover_front = [[5, 67, 50], [22, 255, 255]]
    rover_back = [[55, 50, 50], [80, 255, 255]]

    [vision.aruco]
    dictionary = "DICT_4X4_50"
    rover_id = 1                        # the tag's top edge points where the rover heads
    target_id = 2
    size_m = 0.10                       # side of the black square
    size_tolerance_m = 0.03

    [vision.calibration]                # optional: without it the camera looks straight down and
    corners_px = [[u, v], [u, v], [u, v], [u, v]]   # its frame spans the arena exactly
    width_m = 2.36                      # corners: bottom-left, bottom-right, top-right, top-left
    height_m = 1.75
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

MARKER_KINDS = ("colour", "aruco")

# Shared with the renderer, so that what it draws is what the locator expects.
ROVER_CENTRE_FRACTION = 0.92
MARKER_DISTANCE_M = 0.09
ARUCO_SIZE_M = 0.10

HueRange = tuple[tuple[int, int, int], tuple[int, int, int]]


@dataclass(frozen=True)
class HsvRanges:
    """Lower and upper (H, S, V) bounds of each colour marker, inclusive, OpenCV units."""

    target: HueRange = ((25, 40, 50), (35, 255, 255))
    rover_front: HueRange = ((5, 67, 50), (22, 255, 255))
    rover_back: HueRange = ((55, 50, 50), (80, 255, 255))


@dataclass(frozen=True)
class ArucoConfig:
    dictionary: str = "DICT_4X4_50"
    rover_id: int = 1
    target_id: int = 2
    size_m: float = ARUCO_SIZE_M
    size_tolerance_m: float = 0.03


@dataclass(frozen=True)
class CalibrationConfig:
    """Pixel positions of the arena's corners: bottom-left, bottom-right, top-right, top-left.

    Pixel coordinates are OpenCV's: u to the right, v down, the centre of the top-left pixel at (0, 0).
    """

    corners_px: tuple[tuple[float, float], tuple[float, float], tuple[float, float], tuple[float, float]]
    width_m: float
    height_m: float


@dataclass(frozen=True)
class VisionConfig:
    markers: str = "colour"
    hsv: HsvRanges = field(default_factory=HsvRanges)
    downscale: int = 2
    open_kernel_px: int = 3
    close_kernel_px: int = 3
    min_blob_area_px: float = 40.0
    doubled_area_ratio: float = 0.4
    rover_centre_fraction: float = ROVER_CENTRE_FRACTION
    marker_distance_m: float = MARKER_DISTANCE_M
    marker_distance_tolerance_m: float = 0.03
    max_rover_speed_m_s: float = 0.5
    jump_slack_m: float = 0.03
    aruco: ArucoConfig = field(default_factory=ArucoConfig)
    calibration: CalibrationConfig | None = None

    def __post_init__(self) -> None:
        # Validate objects built in code too, with the same messages as from_dict.
        VisionConfig.from_dict(self.to_dict())

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], prefix: str = "vision") -> VisionConfig:
        """Build from a `[vision]` table; missing keys take their defaults.

        Raises ValueError("vision.KEY: what is wrong") for an unknown key or a bad value.
        """
        _expect_table(d, prefix)
        simple = {f.name for f in fields(cls)} - {"hsv", "aruco", "calibration"}
        _reject_unknown(d, simple | {"hsv", "aruco", "calibration"}, prefix)
        kw: dict[str, Any] = {}
        for key in simple:
            if key in d:
                kw[key] = d[key]
        key = f"{prefix}.markers"
        markers = kw.get("markers", "colour")
        if markers not in MARKER_KINDS:
            raise ValueError(f"{key}: {markers!r} is not one of {', '.join(MARKER_KINDS)}")
        for name in ("downscale", "open_kernel_px", "close_kernel_px"):
            if name in kw:
                kw[name] = _int(kw[name], f"{prefix}.{name}", lo=1, hi=15)
        for name, lo, hi, open_lo in (
            ("min_blob_area_px", 1.0, 1e6, False),
            ("doubled_area_ratio", 0.0, 1.0, True),
            ("rover_centre_fraction", 0.0, 2.0, False),
            ("marker_distance_m", 0.0, 10.0, True),
            ("marker_distance_tolerance_m", 0.0, 10.0, False),
            ("max_rover_speed_m_s", 0.0, 100.0, True),
            ("jump_slack_m", 0.0, 10.0, False),
        ):
            if name in kw:
                kw[name] = _float(kw[name], f"{prefix}.{name}", lo=lo, hi=hi, open_lo=open_lo)
        if "hsv" in d:
            kw["hsv"] = _hsv_from_dict(d["hsv"], f"{prefix}.hsv")
        if "aruco" in d:
            kw["aruco"] = _aruco_from_dict(d["aruco"], f"{prefix}.aruco")
        if "calibration" in d and d["calibration"] is not None:
            kw["calibration"] = _calibration_from_dict(d["calibration"], f"{prefix}.calibration")
        obj = object.__new__(cls)
        defaults = {
            f.name: (f.default_factory() if callable(f.default_factory) else f.default)  # type: ignore[misc]
            for f in fields(cls)
        }
        for name, value in {**defaults, **kw}.items():
            object.__setattr__(obj, name, value)
        return obj

    def to_dict(self) -> dict[str, Any]:
        """The `[vision]` table (calibration left out when there is none); from_dict(to_dict()) == self."""
        d: dict[str, Any] = {
            "markers": self.markers,
            "downscale": self.downscale,
            "open_kernel_px": self.open_kernel_px,
            "close_kernel_px": self.close_kernel_px,
            "min_blob_area_px": self.min_blob_area_px,
            "doubled_area_ratio": self.doubled_area_ratio,
            "rover_centre_fraction": self.rover_centre_fraction,
            "marker_distance_m": self.marker_distance_m,
            "marker_distance_tolerance_m": self.marker_distance_tolerance_m,
            "max_rover_speed_m_s": self.max_rover_speed_m_s,
            "jump_slack_m": self.jump_slack_m,
            "hsv": {
                name: [list(getattr(self.hsv, name)[0]), list(getattr(self.hsv, name)[1])]
                for name in ("target", "rover_front", "rover_back")
            },
            "aruco": {
                "dictionary": self.aruco.dictionary,
                "rover_id": self.aruco.rover_id,
                "target_id": self.aruco.target_id,
                "size_m": self.aruco.size_m,
                "size_tolerance_m": self.aruco.size_tolerance_m,
            },
        }
        if self.calibration is not None:
            d["calibration"] = {
                "corners_px": [list(c) for c in self.calibration.corners_px],
                "width_m": self.calibration.width_m,
                "height_m": self.calibration.height_m,
            }
        return d


def _expect_table(d: Any, key: str) -> None:
    if not isinstance(d, Mapping):
        raise ValueError(f"{key}: expected a table, got {d!r}")


def _reject_unknown(d: Mapping[str, Any], known: set[str], prefix: str) -> None:
    for k in d:
        if k not in known:
            raise ValueError(f"{prefix}.{k}: unknown key (known: {', '.join(sorted(known))})")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _int(v: Any, key: str, lo: int, hi: int) -> int:
    if not _is_number(v) or float(v) != int(v):
        raise ValueError(f"{key}: {v!r} is not a whole number")
    if not lo <= int(v) <= hi:
        raise ValueError(f"{key}: {v!r} is outside [{lo}, {hi}]")
    return int(v)


def _float(v: Any, key: str, lo: float, hi: float, open_lo: bool = False) -> float:
    if not _is_number(v) or not math.isfinite(float(v)):
        raise ValueError(f"{key}: {v!r} is not a number")
    x = float(v)
    if x < lo or x > hi or (open_lo and x == lo):
        bracket = "(" if open_lo else "["
        raise ValueError(f"{key}: {v!r} is outside {bracket}{lo:g}, {hi:g}]")
    return x


_HSV_MAX = (179, 255, 255)


def _hsv_from_dict(d: Any, prefix: str) -> HsvRanges:
    _expect_table(d, prefix)
    names = ("target", "rover_front", "rover_back")
    _reject_unknown(d, set(names), prefix)
    kw = {}
    for name in names:
        if name not in d:
            continue
        key = f"{prefix}.{name}"
        pair = d[name]
        if (
            not isinstance(pair, (list, tuple))
            or len(pair) != 2
            or any(not isinstance(b, (list, tuple)) or len(b) != 3 for b in pair)
        ):
            raise ValueError(f"{key}: expected [[H, S, V], [H, S, V]] (lower, upper), got {pair!r}")
        bounds = []
        for which, b in zip(("lower", "upper"), pair):
            vals = []
            for ch, v, vmax in zip("HSV", b, _HSV_MAX):
                if not _is_number(v) or float(v) != int(v) or not 0 <= int(v) <= vmax:
                    raise ValueError(f"{key}: {which} {ch} {v!r} is not a whole number in [0, {vmax}]")
                vals.append(int(v))
            bounds.append(tuple(vals))
        for ch, a, b in zip("HSV", bounds[0], bounds[1]):
            if a > b:
                raise ValueError(f"{key}: lower bound {a} > upper bound {b} ({ch})")
        kw[name] = (bounds[0], bounds[1])
    return HsvRanges(**kw)


def _aruco_from_dict(d: Any, prefix: str) -> ArucoConfig:
    import cv2

    _expect_table(d, prefix)
    _reject_unknown(d, {f.name for f in fields(ArucoConfig)}, prefix)
    kw: dict[str, Any] = {}
    name = d.get("dictionary", ArucoConfig.dictionary)
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"{prefix}.dictionary: {name!r} is not an OpenCV ArUco dictionary (e.g. DICT_4X4_50)")
    kw["dictionary"] = name
    dict_size = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0]
    for k in ("rover_id", "target_id"):
        if k in d:
            kw[k] = _int(d[k], f"{prefix}.{k}", lo=0, hi=dict_size - 1)
    if kw.get("rover_id", ArucoConfig.rover_id) == kw.get("target_id", ArucoConfig.target_id):
        raise ValueError(f"{prefix}.target_id: {kw.get('target_id', ArucoConfig.target_id)} is also the rover_id")
    if "size_m" in d:
        kw["size_m"] = _float(d["size_m"], f"{prefix}.size_m", 0.0, 10.0, open_lo=True)
    if "size_tolerance_m" in d:
        kw["size_tolerance_m"] = _float(d["size_tolerance_m"], f"{prefix}.size_tolerance_m", 0.0, 10.0)
    return ArucoConfig(**kw)


def _calibration_from_dict(d: Any, prefix: str) -> CalibrationConfig:
    _expect_table(d, prefix)
    _reject_unknown(d, {"corners_px", "width_m", "height_m"}, prefix)
    for k in ("corners_px", "width_m", "height_m"):
        if k not in d:
            raise ValueError(f"{prefix}.{k}: missing")
    corners = d["corners_px"]
    key = f"{prefix}.corners_px"
    if (
        not isinstance(corners, (list, tuple))
        or len(corners) != 4
        or any(not isinstance(c, (list, tuple)) or len(c) != 2 or not all(_is_number(v) for v in c) for c in corners)
    ):
        raise ValueError(
            f"{key}: expected four [u, v] pixel positions (bottom-left, bottom-right, "
            f"top-right, top-left), got {corners!r}"
        )
    pts = tuple((float(c[0]), float(c[1])) for c in corners)
    # In that order the corners of a floor seen by a camera (v down, never mirrored) make a convex
    # quadrilateral that turns the same way at every corner as (0, 480), (640, 480), (640, 0), (0, 0).
    for i in range(4):
        (ax, ay), (bx, by), (cx, cy) = pts[i], pts[(i + 1) % 4], pts[(i + 2) % 4]
        if (bx - ax) * (cy - by) - (by - ay) * (cx - bx) >= 0:
            raise ValueError(
                f"{key}: {corners!r} is not a convex quadrilateral in the order bottom-left, "
                f"bottom-right, top-right, top-left as the camera sees them (out of order or mirrored)"
            )
    w = _float(d["width_m"], f"{prefix}.width_m", 0.0, 1000.0, open_lo=True)
    h = _float(d["height_m"], f"{prefix}.height_m", 0.0, 1000.0, open_lo=True)
    return CalibrationConfig(corners_px=pts, width_m=w, height_m=h)  # type: ignore[arg-type]
