"""Draw a grid, its obstacles and a path into a PNG (OpenCV), for `rovernav plan --plot`."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from .grid import OccupancyGrid

# BGR colours
_FREE = (255, 255, 255)
_INFLATED = (200, 215, 240)
_BODY = (150, 170, 215)
_RAW = (40, 40, 40)
_UNKNOWN = (0, 140, 255)
_PATH = (40, 40, 220)
_CELLS = (150, 150, 230)
_PARTIAL = (200, 60, 200)
_START = (40, 160, 40)
_TARGET = (200, 90, 20)


def render(
    grid: OccupancyGrid,
    path: Sequence[Sequence[float]] | None = None,
    cells: np.ndarray | None = None,
    start: Sequence[float] | None = None,
    goal: Sequence[float] | None = None,
    unknown_boxes: Iterable[tuple[float, float, float, float]] = (),
    partial: Sequence[Sequence[float]] | None = None,
    body: np.ndarray | None = None,
    width_px: int = 800,
) -> np.ndarray:
    """A BGR image of the grid: free white, inflated light red, raw obstacles dark; y up.

    body: a harder layer inside the inflated one (the potential field's robot-radius limit),
    drawn a darker red.
    path: waypoints [m] (red polyline with dots); cells: the raw cell path (light red);
    unknown_boxes: obstacles the planner was not told about (orange outlines); partial: a
    failed descent [m] (magenta); start (green) and goal (blue) markers.
    """
    scale = max(1, int(round(width_px / grid.nx)))
    img = np.empty((grid.ny, grid.nx, 3), dtype=np.uint8)
    img[:] = _FREE
    img[grid.inflated] = _INFLATED
    if body is not None:
        img[body] = _BODY
    img[grid.raw] = _RAW
    img = cv2.resize(img[::-1], (grid.nx * scale, grid.ny * scale), interpolation=cv2.INTER_NEAREST)
    px_per_m = scale / grid.resolution_m
    height = grid.ny * scale

    def px(xy: Sequence[float]) -> tuple[int, int]:
        return int(round(xy[0] * px_per_m)), int(round(height - xy[1] * px_per_m))

    arena_corner = px((grid.width_m, 0.0))
    cv2.rectangle(img, (0, height - 1 - int(round(grid.height_m * px_per_m))), arena_corner, (0, 0, 0), 2)
    for x, y, w, h in unknown_boxes:
        cv2.rectangle(img, px((x - w / 2, y + h / 2)), px((x + w / 2, y - h / 2)), _UNKNOWN, 2)
    if cells is not None and len(cells):
        centres = grid.cells_to_world(cells)
        cv2.polylines(img, [np.array([px(p) for p in centres], dtype=np.int32)], False, _CELLS, 1, cv2.LINE_AA)
    if partial:
        cv2.polylines(img, [np.array([px(p) for p in partial], dtype=np.int32)], False, _PARTIAL, 2, cv2.LINE_AA)
        cv2.drawMarker(img, px(partial[-1]), _PARTIAL, cv2.MARKER_TILTED_CROSS, 18, 2)
    if path:
        pts = np.array([px(p) for p in path], dtype=np.int32)
        cv2.polylines(img, [pts], False, _PATH, 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(img, (int(p[0]), int(p[1])), 4, _PATH, -1, cv2.LINE_AA)
    if start is not None:
        cv2.circle(img, px(start), 8, _START, -1, cv2.LINE_AA)
    if goal is not None:
        cv2.drawMarker(img, px(goal), _TARGET, cv2.MARKER_CROSS, 20, 3)
    return img


def write_png(path: str | Path, image: np.ndarray) -> None:
    """Write `image` to `path`; OSError when it cannot."""
    if not cv2.imwrite(str(path), image):
        raise OSError(f"could not write {path}")
