"""ArUco tags: OpenCV's detector, then each tag's outline refined by fitting its four edges.

A tag's corners come in the order OpenCV gives them: top-left, top-right, bottom-right,
bottom-left of the tag as printed. The rover's tag is mounted with its top edge facing forward,
so its heading is the direction from the bottom edge's midpoint to the top edge's midpoint.

Why refit: at 640 x 480 a 10 cm tag is about 27 pixels wide and its cells 4.5 pixels, so
cornerSubPix's window around an outer corner also holds the inner cells' corners and is pulled
towards them (headings off by 1-3 degrees). The outer edge of the black border against the white
quiet zone is long and clean: sample it across at several points along each side, locate the
edge on each profile to a small fraction of a pixel, fit a line per side and intersect
neighbouring lines (headings then good to about 0.3 degrees at that size).
"""

from __future__ import annotations

import cv2
import numpy as np

from .config import ArucoConfig

# Tags with a shorter outline than this (8 px a side) cannot be decoded at any rate.
_MIN_PERIMETER_PX = 32.0


class ArucoMarkers:
    def __init__(self, config: ArucoConfig):
        self.config = config
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, config.dictionary))
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE  # refine_outline does better
        # Two adaptive-threshold windows instead of OpenCV's three (3, 13, 23 px): each costs about
        # 0.35 ms at 640 x 480, and on rendered frames (tags 18-27 px wide, straight down and
        # oblique) 7 and 17 find every tag the three do.
        params.adaptiveThreshWinSizeMin = 7
        params.adaptiveThreshWinSizeMax = 17
        params.adaptiveThreshWinSizeStep = 10
        self._params = params
        self._detector = cv2.aruco.ArucoDetector(dictionary, params)
        self._cells = dictionary.markerSize + 2
        self.dictionary_size = int(dictionary.bytesList.shape[0])  # its ids are 0 to this - 1

    def find(self, frame_bgr: np.ndarray) -> dict[int, list[np.ndarray]]:
        """Tags found in a BGR uint8 frame: id -> list of (4, 2) float64 corner arrays, in pixels."""
        return self.find_gray(cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY))

    def find_gray(self, gray: np.ndarray, box: tuple[int, int, int, int] | None = None) -> dict[int, list[np.ndarray]]:
        """Tags found in a grey frame, or only within box = (x0, y0, x1, y1) of it (pixels, end exclusive).

        Corners are in the whole frame's pixel coordinates either way.
        """
        x0 = y0 = 0
        view = gray
        if box is not None:
            x0, y0 = max(box[0], 0), max(box[1], 0)
            x1, y1 = min(box[2], gray.shape[1]), min(box[3], gray.shape[0])
            if x1 - x0 < 8 or y1 - y0 < 8:
                return {}
            view = gray[y0:y1, x0:x1]
        # The smallest outline considered is set in pixels, not as OpenCV's fraction of the image, so
        # a small window is not searched for tiny quads in the floor's grain (0.7 ms -> 0.05 ms).
        self._params.minMarkerPerimeterRate = min(_MIN_PERIMETER_PX / max(view.shape), 1.0)
        self._detector.setDetectorParameters(self._params)
        corners, ids, _ = self._detector.detectMarkers(view)
        found: dict[int, list[np.ndarray]] = {}
        if ids is None:
            return found
        for c, i in zip(corners, ids.ravel()):
            rough = np.asarray(c, dtype=np.float64).reshape(4, 2) + (x0, y0)
            found.setdefault(int(i), []).append(refine_outline(gray, rough, self._cells))
        return found


# Across each side: offsets from the current edge estimate, outwards positive, as fractions of
# the half-width of the profile (at most 2.5 px, and never past the black border's or the quiet
# zone's width, one cell each).
_ACROSS_UNIT = np.linspace(-1.0, 1.0, 21)
_ACROSS_MAX_PX = 2.5
_ACROSS_CELLS = 0.6
# Along each side: where to sample, as fractions of the side, clear of the corners.
_ALONG = np.linspace(0.15, 0.85, 11)


def refine_outline(gray: np.ndarray, rough: np.ndarray, cells: int = 6, passes: int = 2) -> np.ndarray:
    """Corners (4, 2) of a tag's outer black square, refined from rough corners by edge fitting.

    The edge's offset along each profile is measured by integration: with the profile scaled to 0
    (black) .. 1 (white), the area above it between -2.5 and +2.5 px is where a sharp step would
    be. Unlike a threshold crossing, this is unbiased wherever the edge falls within a pixel.
    cells: the tag's width in cells, black border included (6 for a 4x4 dictionary).
    Returns the rough corners unchanged when an edge cannot be measured (too small, off the frame,
    no contrast).
    """
    corners = np.asarray(rough, dtype=np.float64)
    for _ in range(passes):
        better = _refine_once(gray, corners, cells)
        if better is None:
            return corners
        corners = better
    return corners


def _refine_once(gray: np.ndarray, corners: np.ndarray, cells: int) -> np.ndarray | None:
    a = corners
    side = np.roll(corners, -1, axis=0) - a  # (4, 2), side i from corner i to i+1
    length = np.hypot(side[:, 0], side[:, 1])
    if length.min() < 8.0:
        return None
    across = _ACROSS_UNIT * min(_ACROSS_MAX_PX, _ACROSS_CELLS * float(length.min()) / cells)
    t = side / length[:, None]
    n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    # Outward: away from the tag's centre.
    if float(np.sum(n * (a + side / 2 - corners.mean(axis=0)), axis=1)[0]) < 0:
        n = -n  # corners all turn the same way
    base = a[:, None, :] + _ALONG[None, :, None] * side[:, None, :]  # (4, K, 2)
    pts = base[:, :, None, :] + across[None, None, :, None] * n[:, None, None, :]  # (4, K, M, 2)
    h, w = gray.shape
    if pts[..., 0].min() < 0 or pts[..., 1].min() < 0 or pts[..., 0].max() > w - 1 or pts[..., 1].max() > h - 1:
        return None
    k, m = len(_ALONG), len(across)
    flat = pts.reshape(4 * k, m, 2).astype(np.float32)
    prof = cv2.remap(gray, flat[..., 0], flat[..., 1], cv2.INTER_LINEAR).astype(np.float32)  # (4K, M)
    inside = prof[:, :3].mean(axis=1)
    contrast = prof[:, -3:].mean(axis=1) - inside
    if contrast.min() < 30.0:
        return None
    dark = np.clip(1.0 - (prof - inside[:, None]) / contrast[:, None], 0.0, 1.0)  # 1 inside, 0 outside
    step = float(across[1] - across[0])
    above = (dark.sum(axis=1) - (dark[:, 0] + dark[:, -1]) / 2) * step  # trapezoid rule
    offset = (across[0] + above).reshape(4, k).astype(np.float64)  # edge offset along n
    # Per side, a straight line through the edge: offset = c0 + c1 * s, s along the side in pixels.
    s_ = _ALONG[None, :] * length[:, None]  # (4, K)
    s_mean, o_mean = s_.mean(axis=1), offset.mean(axis=1)
    ds, do = s_ - s_mean[:, None], offset - o_mean[:, None]
    c1 = (ds * do).sum(axis=1) / (ds * ds).sum(axis=1)
    p = a + s_mean[:, None] * t + o_mean[:, None] * n  # a point on each line
    d = t + c1[:, None] * n  # its direction
    # Corner i joins side i-1 (arriving from corner i-1) and side i (leaving towards corner i+1):
    # solve p[i-1] + u d[i-1] = p[i] + v d[i] for u.
    p1, d1 = np.roll(p, 1, axis=0), np.roll(d, 1, axis=0)
    det = d1[:, 1] * d[:, 0] - d1[:, 0] * d[:, 1]
    if np.abs(det).min() < 1e-9:
        return None
    r = p - p1
    u = (r[:, 1] * d[:, 0] - r[:, 0] * d[:, 1]) / det
    return p1 + u[:, None] * d1
