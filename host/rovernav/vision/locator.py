"""From a camera frame to the rover's pose and the target's position, in arena metres.

    locator = Locator(VisionConfig(), arena_w_m=2.36, arena_h_m=1.75)
    d = locator.locate(frame_bgr, t_s=12.34)
    if d.rover is None:
        log.info("no fix: %s", d.reason)

The contract: a fix is right or absent, never wrong. A frame where a marker is missing, seen
twice, or where the markers make no sense (front and back too near or too far apart, a tag of the
wrong size, a jump from the last fix the rover could not have made at max_rover_speed_m_s) gives
`rover=None` and a `reason` in words. Positions are computed in arena coordinates (both marker
points through the calibration first, then the rover centre and atan2), so an oblique camera
gives right headings too.

Speed (640 x 480, one core of this project's 2-core machine; benchmarks/bench_vision.py): colour
markers about 0.2 ms a frame while tracking (each marker looked for in a window around where it
was in the last frame, the whole frame only when that window does not settle it) and about
0.45 ms for a whole-frame search; ArUco tags about 2 ms for a whole-frame search and about 1 ms
while tracking (both tags looked for in windows around where they were in the last frame, the
whole frame again as soon as either is not there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import cv2
import numpy as np

from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from .aruco_markers import ArucoMarkers
from .calibration import Calibration, heading_deg
from .colour_markers import ColourMarkers
from .config import VisionConfig


class RoverPose(NamedTuple):
    """The rover centre in arena metres; heading 0 = +y (up the image), clockwise, [0, 360) degrees."""

    x_m: float
    y_m: float
    heading_deg: float


class TargetPosition(NamedTuple):
    x_m: float
    y_m: float


@dataclass(frozen=True)
class Detection:
    """What one frame showed.

    rover / target: None when not found; reason / target_reason then say why.
    pixels: the sub-pixel centroids that were found, in the frame's pixel coordinates, by name:
        "front", "back", "target" (colour markers) or "rover", "target" (tag centres).
    areas_px: the area of each marker found, in pixels.
    t_s: the frame time given to locate().
    """

    rover: RoverPose | None
    target: TargetPosition | None
    reason: str | None = None
    target_reason: str | None = None
    pixels: dict[str, tuple[float, float]] = field(default_factory=dict)
    areas_px: dict[str, float] = field(default_factory=dict)
    t_s: float | None = None

    @property
    def front_px(self) -> tuple[float, float] | None:
        return self.pixels.get("front")

    @property
    def back_px(self) -> tuple[float, float] | None:
        return self.pixels.get("back")

    @property
    def target_px(self) -> tuple[float, float] | None:
        return self.pixels.get("target")


_COLOUR_LABEL = {"target": "target marker", "rover_front": "rover front marker", "rover_back": "rover back marker"}
_PIXEL_NAME = {"target": "target", "rover_front": "front", "rover_back": "back"}


_THE_ROVERS = object()  # Locator._jump_problem's default: the rover's own last fix


class Locator:
    """Locates the rover and the target in frames of one camera.

    Keeps the last good fix (and its time) for the jump check; `reset()` forgets it.
    """

    def __init__(
        self,
        config: VisionConfig | None = None,
        arena_w_m: float = DEFAULT_ARENA_WIDTH_MM / 1000.0,
        arena_h_m: float = DEFAULT_ARENA_HEIGHT_MM / 1000.0,
    ):
        self.config = config or VisionConfig()
        if arena_w_m <= 0 or arena_h_m <= 0:
            raise ValueError(f"arena size {arena_w_m} x {arena_h_m} m: both must be positive")
        cal = self.config.calibration
        if cal is not None and (abs(cal.width_m - arena_w_m) > 1e-3 or abs(cal.height_m - arena_h_m) > 1e-3):
            raise ValueError(
                f"vision.calibration: corners of a {cal.width_m} x {cal.height_m} m arena, "
                f"but the arena is {arena_w_m} x {arena_h_m} m"
            )
        self.arena_w_m, self.arena_h_m = float(arena_w_m), float(arena_h_m)
        self._fixed = Calibration.from_config(cal) if cal is not None else None
        self._straight_down: dict[tuple[int, int], Calibration] = {}
        self._colour = ColourMarkers(self.config) if self.config.markers == "colour" else None
        self._aruco = ArucoMarkers(self.config.aruco) if self.config.markers == "aruco" else None
        self._last: tuple[float, float, float | None] | None = None  # x_m, y_m, t_s of the last fix
        self._tag_boxes: dict[int, tuple[int, int, int, int]] = {}  # ArUco tracking windows, pixels
        self._colour_hints: dict[str, tuple[float, float]] = {}  # colour markers' last pixels

    def reset(self) -> None:
        """Forget the last fix (after the rover was moved by hand, say) and where the tags were."""
        self._last = None
        self._tag_boxes = {}
        self._colour_hints = {}

    def _tracked_tags(self, gray: np.ndarray) -> dict[int, list[np.ndarray]] | None:
        """ArUco tracking: the rover's and the target's tags looked for only in windows around where
        they were in the last frame; None (search the whole frame) unless both are found there,
        once each. While tracking, a second rover tag elsewhere in the frame goes unseen: the one
        followed from frame to frame, which passed the jump check, is the rover."""
        acfg = self.config.aruco
        assert self._aruco is not None
        if acfg.rover_id not in self._tag_boxes or acfg.target_id not in self._tag_boxes:
            return None
        tags: dict[int, list[np.ndarray]] = {}
        for tag_id in (acfg.rover_id, acfg.target_id):
            seen = self._aruco.find_gray(gray, self._tag_boxes[tag_id]).get(tag_id, [])
            if len(seen) != 1:
                return None
            tags[tag_id] = seen
        return tags

    def calibration_for(self, width_px: int, height_px: int) -> Calibration:
        """The pixel <-> arena mapping used for frames of this size."""
        if self._fixed is not None:
            return self._fixed
        key = (width_px, height_px)
        if key not in self._straight_down:
            self._straight_down[key] = Calibration.straight_down(width_px, height_px, self.arena_w_m, self.arena_h_m)
        return self._straight_down[key]

    def locate(self, frame_bgr: np.ndarray, t_s: float | None = None) -> Detection:
        """Find the rover and target in a BGR uint8 frame taken at t_s seconds (any clock; None: no jump check)."""
        if frame_bgr.ndim != 3 or frame_bgr.shape[2] != 3 or frame_bgr.dtype != np.uint8:
            raise ValueError(f"frame: expected a BGR uint8 image (H x W x 3), got {frame_bgr.dtype} {frame_bgr.shape}")
        cal = self.calibration_for(frame_bgr.shape[1], frame_bgr.shape[0])
        if self._colour is not None:
            d = self._locate_colour(frame_bgr, cal, t_s)
        else:
            d = self._locate_aruco(frame_bgr, cal, t_s)
        if d.rover is not None:
            self._last = (d.rover.x_m, d.rover.y_m, t_s)
        return d

    # -- checks shared by both marker kinds ---------------------------------------------------------

    def _jump_problem(self, x_m: float, y_m: float, t_s: float | None, last: object = _THE_ROVERS) -> str | None:
        """Why a fix at (x_m, y_m) at t_s is too far from the last one (`last`: (x_m, y_m, t_s) or
        None for none yet; by default the rover's own), or None when it is not."""
        last = self._last if last is _THE_ROVERS else last
        if last is None or t_s is None or last[2] is None:  # type: ignore[index]
            return None
        lx, ly, lt = last  # type: ignore[misc]
        dt = max(t_s - lt, 0.0)
        dist = math.hypot(x_m - lx, y_m - ly)
        allowed = self.config.max_rover_speed_m_s * dt + self.config.jump_slack_m
        if dist > allowed:
            return (
                f"jump of {dist:.2f} m in {dt:.2f} s from the last fix "
                f"(at most {allowed:.2f} m at {self.config.max_rover_speed_m_s:g} m/s)"
            )
        return None

    # -- colour squares -----------------------------------------------------------------------------

    def _locate_colour(self, frame: np.ndarray, cal: Calibration, t_s: float | None) -> Detection:
        cfg = self.config
        assert self._colour is not None
        found = self._colour.find(frame, self._colour_hints)
        self._colour_hints = {name: (r.blob.u_px, r.blob.v_px) for name, r in found.items() if r.blob is not None}
        pixels: dict[str, tuple[float, float]] = {}
        areas: dict[str, float] = {}
        problems: dict[str, str] = {}
        for name, search in found.items():
            colour = self._colour.colour_names[name]
            if search.blob is not None:
                pixels[_PIXEL_NAME[name]] = (search.blob.u_px, search.blob.v_px)
                areas[_PIXEL_NAME[name]] = search.blob.area_px
            elif search.problem == "not found":
                problems[name] = f"{_COLOUR_LABEL[name]} ({colour}) not found"
            else:
                problems[name] = f"{search.problem} {colour} markers"

        target = None
        target_reason = problems.get("target")
        if "target" in pixels:
            tx, ty = cal.to_arena(pixels["target"])
            target = TargetPosition(float(tx), float(ty))

        rover = None
        reason = problems.get("rover_front") or problems.get("rover_back")
        if reason is None:
            front = cal.to_arena(pixels["front"])
            back = cal.to_arena(pixels["back"])
            spacing = float(np.hypot(*(front - back)))
            if abs(spacing - cfg.marker_distance_m) > cfg.marker_distance_tolerance_m:
                reason = (
                    f"markers {spacing:.2f} m apart, expected {cfg.marker_distance_m:.2f} "
                    f"± {cfg.marker_distance_tolerance_m:.2f}"
                )
            else:
                centre = back + cfg.rover_centre_fraction * (front - back)
                reason = self._jump_problem(float(centre[0]), float(centre[1]), t_s)
                if reason is None:
                    rover = RoverPose(float(centre[0]), float(centre[1]), heading_deg(back, front))
        return Detection(rover, target, reason, target_reason, pixels, areas, t_s)

    # -- ArUco tags ---------------------------------------------------------------------------------

    def _locate_aruco(self, frame: np.ndarray, cal: Calibration, t_s: float | None) -> Detection:
        acfg = self.config.aruco
        assert self._aruco is not None
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        tags = self._tracked_tags(gray)
        if tags is None:
            tags = self._aruco.find_gray(gray)
        self._tag_boxes = {
            i: _box_around(c[0]) for i, c in tags.items() if len(c) == 1 and i in (acfg.rover_id, acfg.target_id)
        }
        pixels: dict[str, tuple[float, float]] = {}
        areas: dict[str, float] = {}

        def one(tag_id: int, label: str):
            """(arena corners, None) or (None, problem) for the tag with this id."""
            return tag_corners(tags.get(tag_id, []), tag_id, label, cal, acfg, pixels, areas)

        target = None
        t_corners, target_reason = one(acfg.target_id, "target")
        if t_corners is not None:
            c = t_corners.mean(axis=0)
            target = TargetPosition(float(c[0]), float(c[1]))

        rover = None
        r_corners, reason = one(acfg.rover_id, "rover")
        if r_corners is not None:
            pose = tag_pose(r_corners)
            reason = self._jump_problem(pose.x_m, pose.y_m, t_s)
            if reason is None:
                rover = pose
        return Detection(rover, target, reason, target_reason, pixels, areas, t_s)


def tag_corners(seen: list[np.ndarray], tag_id: int, label: str, cal: Calibration, acfg, pixels: dict, areas: dict):
    """(arena corners, None), or (None, the problem), for the tag with this id given the tags of
    that id found in a frame (`seen`, pixel corners); its centre's pixel and its area go into
    `pixels` and `areas` under `label`."""
    if not seen:
        return None, f"{label} tag (id {tag_id}) not found"
    if len(seen) > 1:
        n = "two" if len(seen) == 2 else str(len(seen))
        return None, f"{n} candidate {label} tags (id {tag_id})"
    px = seen[0]
    pixels[label] = tuple(float(v) for v in _diagonal_crossing(px))
    areas[label] = float(_polygon_area(px))
    corners = cal.to_arena(px)
    side = float(np.mean(np.hypot(*(corners - np.roll(corners, -1, axis=0)).T)))
    if abs(side - acfg.size_m) > acfg.size_tolerance_m:
        return None, f"{label} tag {side:.2f} m wide, expected {acfg.size_m:.2f} ± {acfg.size_tolerance_m:.2f}"
    return corners, None


def tag_pose(corners: np.ndarray) -> RoverPose:
    """A rover's pose from its tag's arena corners (top edge first, facing forward). In the arena
    plane the tag is a true square: its centre is its corners' mean."""
    centre = corners.mean(axis=0)
    top = (corners[0] + corners[1]) / 2
    bottom = (corners[2] + corners[3]) / 2
    return RoverPose(float(centre[0]), float(centre[1]), heading_deg(bottom, top))


def _box_around(corners_px: np.ndarray) -> tuple[int, int, int, int]:
    """The window to look for a tag in next frame: its bounding box grown by one tag width
    (about 0.1 m: three times what the rover covers between frames at 0.5 m/s and 15 fps)."""
    lo, hi = corners_px.min(axis=0), corners_px.max(axis=0)
    grow = max(float((hi - lo).max()), 16.0)
    return (int(lo[0] - grow), int(lo[1] - grow), int(hi[0] + grow) + 1, int(hi[1] + grow) + 1)


def _polygon_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _diagonal_crossing(p: np.ndarray) -> np.ndarray:
    """Where a quadrilateral's diagonals cross: the image of a square's centre under any homography."""
    a, c, b, d = p[0], p[2], p[1], p[3]
    r, s = c - a, d - b
    den = r[0] * s[1] - r[1] * s[0]
    if abs(den) < 1e-12:
        return p.mean(axis=0)
    t = ((b[0] - a[0]) * s[1] - (b[1] - a[1]) * s[0]) / den
    return a + t * r
