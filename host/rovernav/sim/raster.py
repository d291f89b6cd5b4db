"""The renderer's drawing primitives: rectangles in a body's frame, shapes projected to pixels and
filled with sub-pixel accuracy (a shape's coverage of each pixel is the mean of an 8 x 8 grid of
sub-pixels, each itself anti-aliased), blended into planar float images, ArUco tag patterns and
lighting an albedo into a uint8 BGR picture. Used by rovernav.sim.camera's Renderer.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .scene import BGR

_SUPERSAMPLE = 8  # sub-pixels per pixel side when filling shapes (a power of 2)
_SHIFT_BITS = 8  # fixed-point fraction bits given to cv2.fillPoly


def _forward_right(heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
    h = math.radians(heading_deg)
    return np.array([math.sin(h), math.cos(h)]), np.array([math.cos(h), -math.sin(h)])


def _rect(centre, forward, right, length_m: float, width_m: float) -> np.ndarray:
    """Corners (4, 2) of a rectangle: length along forward, width along right."""
    c = np.asarray(centre, dtype=np.float64)
    f = forward * (length_m / 2)
    r = right * (width_m / 2)
    return np.array([c + f - r, c + f + r, c - f + r, c - f - r])


def _rect_local(forward_m: float, length_m: float, width_m: float) -> np.ndarray:
    """`_rect`'s corners in a body's own frame, (along forward, along right), centred forward_m ahead."""
    f, r = length_m / 2, width_m / 2
    return np.array([(forward_m + f, -r), (forward_m + f, r), (forward_m - f, r), (forward_m - f, -r)])


# A shape to paint: polygons (pixel coordinates) filled together in one colour.
_Shape = tuple[list[np.ndarray], BGR]


def _group(corners: np.ndarray, groups: list[tuple[int, BGR]]) -> list[_Shape]:
    """Quadrilaterals' corners (N x 4 x 2) split into shapes: [(count, colour), ...] in order."""
    shapes, i = [], 0
    for n, bgr in groups:
        shapes.append((list(corners[i : i + n]), bgr))
        i += n
    return shapes


def _coverage(polys_px: list[np.ndarray], shape_hw: tuple[int, int]):
    """Fraction of each pixel covered by the union of polygons (pixel coordinates).

    Returns (x0, y0, coverage float32) for the window of the frame the polygons touch, clipped to
    the frame, or None when they miss it.
    """
    allp = polys_px[0] if len(polys_px) == 1 else np.concatenate(polys_px)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    x0, y0 = max(math.floor(lo[0]) - 1, 0), max(math.floor(lo[1]) - 1, 0)
    x1, y1 = min(math.ceil(hi[0]) + 2, shape_hw[1]), min(math.ceil(hi[1]) + 2, shape_hw[0])
    if x1 <= x0 or y1 <= y0:
        return None
    s = _SUPERSAMPLE
    buf = np.zeros(((y1 - y0) * s, (x1 - x0) * s), np.uint8)
    # Sub-pixel k of pixel u has its centre at u - 0.5 + (k + 0.5) / s, so pixel position p maps to
    # s * (p - origin) + (s - 1) / 2 in the supersampled buffer, given to fillPoly in fixed point.
    one = 1 << _SHIFT_BITS
    fixed = np.rint((allp - (x0, y0)) * float(s * one) + (s - 1) / 2 * one).astype(np.int32)
    pts = [fixed] if len(polys_px) == 1 else np.split(fixed, np.cumsum([len(p) for p in polys_px[:-1]]))
    # Anti-aliased edges in the supersampled buffer too: without, an edge moves in steps of 1/8 px.
    cv2.fillPoly(buf, pts, 255, lineType=cv2.LINE_AA, shift=_SHIFT_BITS)
    # Box-average each s x s block down to one pixel, in halvings: OpenCV's INTER_AREA has a fast
    # path for exactly 2:1 and a slow general one (an 8:1 step took 4 times as long as three 2:1
    # steps). Each halving rounds to 1/255, so a coverage may be 1/255 off the exact block mean.
    small = buf
    while small.shape[0] > y1 - y0:
        small = cv2.resize(small, (small.shape[1] // 2, small.shape[0] // 2), interpolation=cv2.INTER_AREA)
    return x0, y0, small.astype(np.float32) * (1.0 / 255.0)


def _paint(img: np.ndarray, polys_px: list[np.ndarray], bgr) -> None:
    """Blend a colour into img over the polygons' coverage, in place. img is float32 and planar,
    3 x H x W (B, G, R planes): blending a coverage into planes is several times faster than into
    interleaved H x W x 3 pixels, where numpy broadcasts over an axis of 3."""
    got = _coverage(polys_px, img.shape[1:])
    if got is None:
        return
    x0, y0, cov = got
    h, w = cov.shape
    roi = img[:, y0 : y0 + h, x0 : x0 + w]
    roi *= 1.0 - cov
    roi += cov * np.asarray(bgr, dtype=np.float32)[:, None, None]


_TAG_PATTERNS: dict[tuple[str, int], np.ndarray] = {}


def _tag_pattern(dictionary: str, tag_id: int) -> np.ndarray:
    """The tag's cells including its black border, True where black; row 0 is the tag's top."""
    key = (dictionary, tag_id)
    if key not in _TAG_PATTERNS:
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        cells = d.markerSize + 2
        img = cv2.aruco.generateImageMarker(d, tag_id, cells)
        _TAG_PATTERNS[key] = img < 128
    return _TAG_PATTERNS[key]


def _window(polys_px: list[np.ndarray], margin_px: int, shape_hw: tuple[int, int]):
    """The pixel window (x0, y0, x1, y1) holding the polygons and margin_px more round them (at
    least the window `_coverage` fills for each of them), clipped to the frame; None if empty."""
    allp = np.concatenate(polys_px)
    x0 = max(int(math.floor(allp[:, 0].min())) - max(margin_px, 1), 0)
    y0 = max(int(math.floor(allp[:, 1].min())) - max(margin_px, 1), 0)
    x1 = min(int(math.ceil(allp[:, 0].max())) + max(margin_px, 2), shape_hw[1])
    y1 = min(int(math.ceil(allp[:, 1].max())) + max(margin_px, 2), shape_hw[0])
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


def _light_up(albedo: np.ndarray, light: np.ndarray) -> np.ndarray:
    """The camera's picture of an albedo (float32, planar 3 x H x W) under a light factor (H x W):
    uint8 H x W x 3."""
    lit = albedo * light
    planes = np.clip(np.rint(lit, out=lit), 0, 255, out=lit).astype(np.uint8)
    return cv2.merge(list(planes))
