"""Find the rover (front and back markers) and the target in an overhead frame.

Colour markers (the seed's): threshold in HSV on a copy `downscale` times smaller, clean the
masks with a morphological open and close, take the connected components, then refine each
marker's centroid at full resolution from the image moments of a small window around it, in
floating point (the seed rounded centroids to whole pixels and its heading jumped by 2.5 degrees
on a still scene). Pixel positions go to arena metres through the calibration, and the heading
is computed there, by atan2, 0 degrees up the arena (+y), clockwise: an oblique camera gives the
right heading and there are no quadrant cases.

ArUco markers: OpenCV's detector; the rover's tag gives its centre and, from its top edge, its
heading; the target's tag its position.

A frame where a marker is missing, doubled, or implausible (markers too far apart or too close,
a jump the rover could not have made) gives no fix and says why. Never a wrong fix.
"""
from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from .calibration import Calibration, heading_deg
from .config import VisionConfig


@dataclasses.dataclass(frozen=True)
class Detection:
    """rover: (x_m, y_m, heading_deg) or None; target: (x_m, y_m) or None; reason: why no rover."""

    rover: tuple[float, float, float] | None
    target: tuple[float, float] | None
    reason: str | None = None
    front_px: tuple[float, float] | None = None
    back_px: tuple[float, float] | None = None
    target_px: tuple[float, float] | None = None


class _Blob(tuple):
    pass


class Locator:
    """Stateful only in what plausibility needs: the last accepted fix and its time."""

    COLOUR_NAMES = {"rover_front": "rover front marker (orange)", "rover_back": "rover back marker (green)",
                    "target": "target marker (yellow)"}

    def __init__(self, config: VisionConfig, arena_w_m: float, arena_h_m: float):
        self.cfg = config
        self.arena_w_m, self.arena_h_m = arena_w_m, arena_h_m
        self._cal: Calibration | None = Calibration.from_config(config.calibration) if config.calibration else None
        self._cal_size: tuple[int, int] | None = None
        self._last: tuple[float, float, float] | None = None   # x, y, t
        self._hints: dict[str, tuple[float, float]] = {}       # marker -> last pixel position
        self._hsv_small: np.ndarray | None = None
        self._hsv_small_of: np.ndarray | None = None
        k_open, k_close = config.open_kernel_px, config.close_kernel_px
        self._k_open = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k_open, k_open)) if k_open > 1 else None
        self._k_close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k_close, k_close)) if k_close > 1 else None
        hsv = config.hsv
        self._ranges = {name: (np.array(getattr(hsv, name)[0], np.uint8), np.array(getattr(hsv, name)[1], np.uint8))
                        for name in ("rover_front", "rover_back", "target")}
        self._aruco = None
        if config.markers == "aruco":
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, config.aruco.dictionary))
            params = cv2.aruco.DetectorParameters()
            params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
            self._aruco = cv2.aruco.ArucoDetector(dictionary, params)

    def calibration(self, width_px: int, height_px: int) -> Calibration:
        if self._cal is not None:
            return self._cal
        if self._cal_size != (width_px, height_px):
            self._cal_size = (width_px, height_px)
            self._straight = Calibration.straight_down(width_px, height_px, self.arena_w_m, self.arena_h_m)
        return self._straight

    def reset(self) -> None:
        """Forget the last fix (the jump check starts afresh) and where the markers were."""
        self._last = None
        self._hints = {}

    def locate(self, frame_bgr: np.ndarray, t_s: float | None = None) -> Detection:
        if frame_bgr is None or frame_bgr.ndim != 3 or frame_bgr.shape[2] != 3:
            raise ValueError("locate() needs a BGR colour image (height x width x 3)")
        cal = self.calibration(frame_bgr.shape[1], frame_bgr.shape[0])
        if self._aruco is not None:
            return self._locate_aruco(frame_bgr, cal, t_s)
        return self._locate_colour(frame_bgr, cal, t_s)

    # ---------------------------------------------------------------- colour

    # Markers move little between frames: look first in a window around where each was last
    # seen (about 0.5 m square for the rover at the seed's scale), and in the whole frame only
    # when that fails. The result is the same; the window is only faster.
    ROVER_WINDOW_PX = 100
    TARGET_WINDOW_PX = 40

    def _locate_colour(self, frame: np.ndarray, cal: Calibration, t_s: float | None) -> Detection:
        found: dict[str, tuple[float, float] | str] = {}
        hints = self._hints
        windows: dict[tuple, tuple[np.ndarray, np.ndarray, int, int]] = {}   # one HSV window per area
        for name, half in (("rover_front", self.ROVER_WINDOW_PX), ("rover_back", self.ROVER_WINDOW_PX),
                           ("target", self.TARGET_WINDOW_PX)):
            hint = hints.get(name)
            result: tuple[float, float] | str = "not looked"
            if hint is not None:
                # The rover's two markers share the window around the front marker's last place.
                u, v = hints.get("rover_front", hint) if name.startswith("rover") else hint
                x0, y0 = max(0, int(u) - half), max(0, int(v) - half)
                x1, y1 = min(frame.shape[1], int(u) + half), min(frame.shape[0], int(v) + half)
                key = (x0, y0, x1, y1)
                ds = 2 if half > 50 else 1   # big windows are thresholded at half size too
                if key not in windows and x1 > x0 and y1 > y0:
                    window = frame[y0:y1, x0:x1]
                    small = cv2.resize(window, ((x1 - x0) // ds, (y1 - y0) // ds),
                                       interpolation=cv2.INTER_AREA) if ds > 1 else window
                    windows[key] = (window, cv2.cvtColor(small, cv2.COLOR_BGR2HSV), x0, y0)
                if key in windows:
                    window, hsv, wx, wy = windows[key]
                    result = self._find(name, hsv, window, ds, edge_ok=False)
                    if isinstance(result, tuple):
                        result = (result[0] + wx, result[1] + wy)
            if not isinstance(result, tuple):
                if self._hsv_small_of is not frame:
                    ds = self.cfg.downscale
                    small = cv2.resize(frame, (frame.shape[1] // ds, frame.shape[0] // ds),
                                       interpolation=cv2.INTER_AREA) if ds > 1 else frame
                    self._hsv_small, self._hsv_small_of = cv2.cvtColor(small, cv2.COLOR_BGR2HSV), frame
                result = self._find(name, self._hsv_small, frame, self.cfg.downscale)
            found[name] = result
        self._hsv_small_of = None
        self._hints = {name: v for name, v in found.items() if isinstance(v, tuple)}
        target_px = found["target"] if isinstance(found["target"], tuple) else None
        target = tuple(float(v) for v in cal.to_arena(np.array([target_px]))[0]) if target_px else None
        for name in ("rover_front", "rover_back"):
            if isinstance(found[name], str):
                return Detection(None, target, found[name], target_px=target_px)
        front_px, back_px = found["rover_front"], found["rover_back"]
        front_m, back_m = cal.to_arena(np.array([front_px, back_px]))
        return self._rover_from(front_m, back_m, target, t_s, front_px, back_px, target_px)

    def _find(self, name: str, hsv_small: np.ndarray, frame: np.ndarray, ds: int,
              edge_ok: bool = True) -> tuple[float, float] | str:
        """The marker's centroid in frame pixels, or why there is none. hsv_small is frame in HSV,
        downscaled by ds. With edge_ok False (a window), a blob touching the window's edge is
        refused, so that a marker cut by the window is looked for again in the whole frame."""
        lo, hi = self._ranges[name]
        mask = cv2.inRange(hsv_small, lo, hi)
        if self._k_open is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._k_open)
        if self._k_close is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._k_close)
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        min_area = self.cfg.min_blob_area_px / (ds * ds)
        blobs = sorted((stats[i] for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= min_area),
                       key=lambda s: -s[cv2.CC_STAT_AREA])
        what = self.COLOUR_NAMES[name]
        if not blobs:
            return f"{what} not found"
        if len(blobs) > 1 and blobs[1][cv2.CC_STAT_AREA] >= self.cfg.doubled_area_ratio * blobs[0][cv2.CC_STAT_AREA]:
            return f"two candidate {what.split(' (')[0].replace(' marker', '')} markers ({what.split('(')[1][:-1]})"
        x, y, w, h = (int(v) for v in blobs[0][:4])
        if not edge_ok and (x == 0 or y == 0 or x + w >= hsv_small.shape[1] or y + h >= hsv_small.shape[0]):
            return f"{what} at the edge of the search window"
        # Refine at full resolution in a window around the blob.
        pad = 2 * ds
        x0, y0 = max(0, x * ds - pad), max(0, y * ds - pad)
        x1, y1 = min(frame.shape[1], (x + w) * ds + pad), min(frame.shape[0], (y + h) * ds + pad)
        roi = hsv_small[y0:y1, x0:x1] if ds == 1 else cv2.cvtColor(frame[y0:y1, x0:x1], cv2.COLOR_BGR2HSV)
        fine = cv2.inRange(roi, lo, hi)
        if self._k_open is not None:
            fine = cv2.morphologyEx(fine, cv2.MORPH_OPEN, self._k_open)
        m = cv2.moments(fine, binaryImage=True)
        if m["m00"] < self.cfg.min_blob_area_px * 0.5:
            return f"{what} not found"
        return (x0 + m["m10"] / m["m00"], y0 + m["m01"] / m["m00"])

    # ---------------------------------------------------------------- ArUco

    def _locate_aruco(self, frame: np.ndarray, cal: Calibration, t_s: float | None) -> Detection:
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        corners, ids, _ = self._aruco.detectMarkers(gray)
        a = self.cfg.aruco
        rover_tags, target_tags = [], []
        if ids is not None:
            for c, i in zip(corners, ids.ravel()):
                if i == a.rover_id:
                    rover_tags.append(c.reshape(4, 2))
                elif i == a.target_id:
                    target_tags.append(c.reshape(4, 2))
        target = target_px = None
        if len(target_tags) == 1:
            target_px = tuple(float(v) for v in target_tags[0].mean(axis=0))
            target = tuple(float(v) for v in cal.to_arena(np.array([target_px]))[0])
        if not rover_tags:
            return Detection(None, target, f"rover tag (id {a.rover_id}) not found", target_px=target_px)
        if len(rover_tags) > 1:
            return Detection(None, target, f"two rover tags (id {a.rover_id}) in view", target_px=target_px)
        c_m = cal.to_arena(rover_tags[0])   # corners: top-left, top-right, bottom-right, bottom-left
        side = float(np.mean([np.linalg.norm(c_m[i] - c_m[(i + 1) % 4]) for i in range(4)]))
        if abs(side - a.size_m) > a.size_tolerance_m:
            return Detection(None, target, f"rover tag {side:.3f} m wide, expected {a.size_m:.3f} "
                                           f"± {a.size_tolerance_m:.3f}: not the rover's", target_px=target_px)
        centre = c_m.mean(axis=0)
        top_mid, bottom_mid = (c_m[0] + c_m[1]) / 2, (c_m[2] + c_m[3]) / 2
        heading = heading_deg(bottom_mid, top_mid)
        return self._accept(float(centre[0]), float(centre[1]), heading, target, t_s,
                            None, None, target_px)

    # ---------------------------------------------------------------- plausibility

    def _rover_from(self, front_m, back_m, target, t_s, front_px, back_px, target_px) -> Detection:
        cfg = self.cfg
        d = float(np.hypot(*(front_m - back_m)))
        if abs(d - cfg.marker_distance_m) > cfg.marker_distance_tolerance_m:
            return Detection(None, target, f"markers {d:.3f} m apart, expected {cfg.marker_distance_m:.2f} "
                                           f"± {cfg.marker_distance_tolerance_m:.2f}", front_px, back_px, target_px)
        centre = back_m + cfg.rover_centre_fraction * (front_m - back_m)
        return self._accept(float(centre[0]), float(centre[1]), heading_deg(back_m, front_m), target, t_s,
                            front_px, back_px, target_px)

    def _accept(self, x, y, heading, target, t_s, front_px, back_px, target_px) -> Detection:
        cfg = self.cfg
        if t_s is not None and self._last is not None:
            lx, ly, lt = self._last
            dt = t_s - lt
            jump = math.hypot(x - lx, y - ly)
            if 0 <= dt < 2.0 and jump > cfg.max_rover_speed_m_s * dt + cfg.jump_slack_m:
                return Detection(None, target, f"jump of {jump:.2f} m in {dt:.2f} s: faster than "
                                               f"{cfg.max_rover_speed_m_s:.2f} m/s", front_px, back_px, target_px)
        if t_s is not None:
            self._last = (x, y, t_s)
        heading = (heading + 180.0) % 360.0 - 180.0
        return Detection((x, y, heading), target, None, front_px, back_px, target_px)
