"""Pixels to arena metres and back, through a homography of the floor plane.

Pixel coordinates are OpenCV's: u to the right, v down, the centre of the top-left pixel at
(0, 0), so a W x H frame spans [-0.5, W - 0.5] x [-0.5, H - 0.5]. Arena coordinates are metres
from the arena's bottom-left corner as the camera sees it, x to the right, y up.

Two ways to get a `Calibration`:
- `Calibration.from_corners`: the four arena corners as seen in the image (bottom-left,
  bottom-right, top-right, top-left). Any camera pose works, straight down or oblique.
- `Calibration.straight_down`: the seed's set-up, a camera looking straight down whose frame
  spans the arena exactly: x = (u + 0.5) * W / width_px, y = (height_px - v - 0.5) * H / height_px.
  (The seed wrote x = u * W / width_px, treating a pixel's index as its left edge; with sub-pixel
  centroids the half pixel, about 1.8 mm on the seed's arena, is worth getting right.)

Only points on the floor plane map exactly; a marker on the rover's top, above the floor, is
seen displaced away from the image's principal point (parallax), which neither mapping knows.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..angles import compass_deg
from .config import CalibrationConfig


class Calibration:
    """A homography between the image and the arena floor."""

    def __init__(self, pixel_from_arena: np.ndarray, arena_w_m: float, arena_h_m: float):
        m = np.asarray(pixel_from_arena, dtype=np.float64)
        if m.shape != (3, 3) or abs(np.linalg.det(m)) < 1e-12:
            raise ValueError(f"pixel_from_arena: expected an invertible 3x3 matrix, got {m!r}")
        self.pixel_from_arena = m / m[2, 2]
        self.arena_from_pixel = np.linalg.inv(self.pixel_from_arena)
        self._axis_scales = _axis_scales(self.arena_from_pixel)
        self.arena_w_m = float(arena_w_m)
        self.arena_h_m = float(arena_h_m)

    @classmethod
    def from_corners(cls, corners_px, width_m: float, height_m: float) -> Calibration:
        """corners_px: pixel positions of the arena's bottom-left, bottom-right, top-right, top-left corners."""
        src = np.array([[0.0, 0.0], [width_m, 0.0], [width_m, height_m], [0.0, height_m]], dtype=np.float32)
        dst = np.asarray(corners_px, dtype=np.float32).reshape(4, 2)
        return cls(cv2.getPerspectiveTransform(src, dst).astype(np.float64), width_m, height_m)

    @classmethod
    def from_config(cls, cal: CalibrationConfig) -> Calibration:
        return cls.from_corners(cal.corners_px, cal.width_m, cal.height_m)

    @classmethod
    def straight_down(cls, width_px: int, height_px: int, arena_w_m: float, arena_h_m: float) -> Calibration:
        """The frame spans the arena exactly, seen from straight above (the seed's set-up)."""
        sx = width_px / arena_w_m
        sy = height_px / arena_h_m
        m = np.array([[sx, 0.0, -0.5], [0.0, -sy, height_px - 0.5], [0.0, 0.0, 1.0]])
        return cls(m, arena_w_m, arena_h_m)

    @staticmethod
    def _apply(m: np.ndarray, pts) -> np.ndarray:
        p = np.asarray(pts, dtype=np.float64)
        flat = p.reshape(-1, 2)
        w = flat @ m[:2, :2].T + m[:2, 2]
        d = flat @ m[2, :2] + m[2, 2]
        return (w / d[:, None]).reshape(p.shape)

    def to_arena(self, pts_px) -> np.ndarray:
        """(u, v) pixels, shape (2,) or (N, 2) -> (x, y) metres, same shape."""
        if self._axis_scales is not None and type(pts_px) is tuple and len(pts_px) == 2:
            # One point (the locator's markers) through a mapping that only scales and shifts each
            # axis (a camera straight down): what _apply computes, without its array overhead.
            ax, bx, ay, by = self._axis_scales
            return np.array((pts_px[0] * ax + bx, pts_px[1] * ay + by))
        return self._apply(self.arena_from_pixel, pts_px)

    def to_pixels(self, pts_m) -> np.ndarray:
        """(x, y) metres, shape (2,) or (N, 2) -> (u, v) pixels, same shape."""
        return self._apply(self.pixel_from_arena, pts_m)

    def pixels_per_metre(self, x_m: float, y_m: float) -> float:
        """Local scale at an arena point: the square root of the area one square metre covers there."""
        j = self.jacobian_px_per_m(x_m, y_m)
        return math.sqrt(abs(float(np.linalg.det(j))))

    def jacobian_px_per_m(self, x_m: float, y_m: float) -> np.ndarray:
        """d(u, v)/d(x, y) at an arena point, 2x2."""
        m = self.pixel_from_arena
        num = m[:2, :2] @ np.array([x_m, y_m]) + m[:2, 2]
        den = float(m[2, :2] @ np.array([x_m, y_m]) + m[2, 2])
        return (m[:2, :2] * den - np.outer(num, m[2, :2])) / (den * den)


def _axis_scales(m: np.ndarray) -> tuple[float, float, float, float] | None:
    """(ax, bx, ay, by) when m maps (u, v) to (ax * u + bx, ay * v + by), with bx and by not zero;
    else None. For such an m, _apply gives those values bit for bit: the products with m's zeros
    are zeros, which change no sum with a non-zero term however the matrix product orders or fuses
    its operations, the denominator is exactly 1 and a division by 1 is exact."""
    if m[0, 1] == 0 and m[1, 0] == 0 and m[2, 0] == 0 and m[2, 1] == 0 and m[2, 2] == 1 and m[0, 2] and m[1, 2]:
        return float(m[0, 0]), float(m[0, 2]), float(m[1, 1]), float(m[1, 2])
    return None


def heading_deg(back_m, front_m) -> float:
    """Heading of the vector back -> front in arena coordinates: 0 = +y, clockwise positive, [0, 360)."""
    dx = float(front_m[0]) - float(back_m[0])
    dy = float(front_m[1]) - float(back_m[1])
    return compass_deg(math.degrees(math.atan2(dx, dy)))
