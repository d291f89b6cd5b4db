"""Overhead camera frames of the arena, drawn from a scene: the simulator's camera and the
vision tests' ground truth.

A frame is drawn as a camera would see the floor plane: tiled floor with grain and mottling,
obstacle boxes (a neutral grey that no marker's HSV range accepts), the target marker, the rover
(a dark 0.15 m x 0.21 m body with its orange front and green back squares, or an ArUco tag),
then multiplied by an uneven light (a gradient and a vignette) and given Gaussian sensor noise.

Every shape is projected through the calibration's homography (arena metres -> pixels), so an
oblique camera is drawn as exactly as a straight-down one, and filled with sub-pixel accuracy by
supersampling: a shape's coverage of each pixel is the mean of an 8 x 8 grid of sub-pixels, each
itself anti-aliased, so a marker moved by a tenth of a pixel moves its rendered centroid by a
tenth of a pixel (to within 0.02 px).

Speed: the floor, obstacles and target are drawn once per scene and cached; a frame then costs a
copy, the rover (a few small patches) and the noise (a random window into a bank of Gaussian
noise drawn once), about a millisecond for 640 x 480.

Conventions are the vision package's: arena metres from the bottom-left corner, x right, y up;
heading 0 = +y (up the image), clockwise positive, degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from .vision.calibration import Calibration
from .vision.config import ARUCO_SIZE_M, MARKER_DISTANCE_M, ROVER_CENTRE_FRACTION, VisionConfig

BGR = tuple[int, int, int]

_SUPERSAMPLE = 8          # sub-pixels per pixel side when filling shapes
_SHIFT_BITS = 8           # fixed-point fraction bits given to cv2.fillPoly
_NOISE_PAD = 48           # the noise bank is this much larger than a frame on each axis


@dataclass(frozen=True)
class Scene:
    """What is in the arena at one instant.

    obstacles: boxes as (centre x, centre y, width, height) in metres, axis-aligned.
    rover: (x_m, y_m, heading_deg) of the rover centre, or None for an empty arena.
    target: (x_m, y_m) or None.
    marker_kind: "colour" (orange front, green back, yellow target squares) or "aruco" (tags).
    hidden: rover markers left undrawn, to imitate occlusion or a lost sticker: "front", "back"
        (colour squares) or "tag" (the rover's ArUco tag).
    decoys: extra markers lying on the floor, each (kind, x_m, y_m) with kind "front", "back" or
        "target" (a colour square like that marker) or an int (an ArUco tag with that id).
    """

    arena_w_m: float = 2.36
    arena_h_m: float = 1.75
    obstacles: tuple[tuple[float, float, float, float], ...] = ()
    rover: tuple[float, float, float] | None = None
    target: tuple[float, float] | None = None
    marker_kind: str = "colour"
    hidden: frozenset[str] = frozenset()
    decoys: tuple[tuple[str | int, float, float], ...] = ()


@dataclass(frozen=True)
class RoverLook:
    """Sizes (metres) and colours (BGR) of what is drawn.

    The colour squares sit on the rover's centre line so that the rover centre is
    back + centre_fraction * (front - back), the rule the locator uses, with the squares'
    centres marker_distance_m apart. The body's centre is body_offset_m ahead of the rover centre.
    The rover's ArUco tag is centred on the rover centre, its top edge facing forward.
    """

    body_length_m: float = 0.21
    body_width_m: float = 0.15
    body_offset_m: float = -0.005
    marker_size_m: float = 0.05
    marker_distance_m: float = MARKER_DISTANCE_M
    centre_fraction: float = ROVER_CENTRE_FRACTION
    target_size_m: float = 0.06
    aruco_size_m: float = ARUCO_SIZE_M
    aruco_dictionary: str = "DICT_4X4_50"
    rover_tag_id: int = 1
    target_tag_id: int = 2
    body_bgr: BGR = (34, 32, 30)
    front_bgr: BGR = (30, 110, 235)      # orange: OpenCV H 12, inside Table 4.1's 5-22
    back_bgr: BGR = (70, 175, 45)        # green: H 66, inside 55-80
    target_bgr: BGR = (40, 215, 220)     # yellow: H 29, inside 25-35
    obstacle_bgr: BGR = (118, 124, 130)  # warm grey, S about 24: below every marker's S floor
    obstacle_rim_bgr: BGR = (92, 96, 100)
    floor_bgr: BGR = (150, 156, 162)
    grout_bgr: BGR = (118, 121, 124)
    outside_bgr: BGR = (64, 64, 64)      # beyond the arena, when an oblique camera sees past it

    @classmethod
    def for_vision(cls, config: VisionConfig, **overrides) -> "RoverLook":
        """A look that matches a VisionConfig's geometry and ArUco settings."""
        kw = dict(marker_distance_m=config.marker_distance_m, centre_fraction=config.rover_centre_fraction,
                  aruco_size_m=config.aruco.size_m, aruco_dictionary=config.aruco.dictionary,
                  rover_tag_id=config.aruco.rover_id, target_tag_id=config.aruco.target_id)
        kw.update(overrides)
        return cls(**kw)


@dataclass(frozen=True)
class Lighting:
    """Light falling on the floor, as a factor on each pixel's colour.

    factor = level * (1 + gradient * s) * (1 - vignette * r^2), where s in [-1, 1] runs across the
    frame towards gradient_angle_deg (0 = towards the top of the image, clockwise) and r is the
    distance from the frame centre, 1 at the corners.
    """

    level: float = 1.0
    gradient: float = 0.2
    gradient_angle_deg: float = 35.0
    vignette: float = 0.3

    @classmethod
    def uniform(cls) -> "Lighting":
        return cls(level=1.0, gradient=0.0, vignette=0.0)

    @classmethod
    def random(cls, rng: np.random.Generator) -> "Lighting":
        """A plausible uneven light: between about 0.5 and 1.2 across the frame."""
        return cls(level=float(rng.uniform(0.9, 1.05)), gradient=float(rng.uniform(0.05, 0.25)),
                   gradient_angle_deg=float(rng.uniform(0.0, 360.0)), vignette=float(rng.uniform(0.1, 0.35)))

    def factor(self, width_px: int, height_px: int) -> np.ndarray:
        """The light factor of every pixel, float32 (height_px, width_px)."""
        u = (np.arange(width_px, dtype=np.float32) - (width_px - 1) / 2) / (width_px / 2)
        v = (np.arange(height_px, dtype=np.float32) - (height_px - 1) / 2) / (height_px / 2)
        uu, vv = np.meshgrid(u, v)
        a = math.radians(self.gradient_angle_deg)
        s = (uu * math.sin(a) - vv * math.cos(a)) / max(abs(math.sin(a)) + abs(math.cos(a)), 1e-9)
        r2 = (uu * uu + vv * vv) / 2.0
        return (self.level * (1 + self.gradient * s) * (1 - self.vignette * r2)).astype(np.float32)


@dataclass(frozen=True)
class Camera:
    """The camera: frame size, where it looks (None: straight down, the frame spanning the arena),
    the light it sees and its sensor noise (standard deviation in grey levels, 0-255)."""

    width_px: int = 640
    height_px: int = 480
    calibration: Calibration | None = None
    lighting: Lighting = field(default_factory=Lighting)
    noise_sigma: float = 3.0

    def mapping(self, arena_w_m: float, arena_h_m: float) -> Calibration:
        if self.calibration is not None:
            return self.calibration
        return Calibration.straight_down(self.width_px, self.height_px, arena_w_m, arena_h_m)


def _forward_right(heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
    h = math.radians(heading_deg)
    return np.array([math.sin(h), math.cos(h)]), np.array([math.cos(h), -math.sin(h)])


def _rect(centre, forward, right, length_m: float, width_m: float) -> np.ndarray:
    """Corners (4, 2) of a rectangle: length along forward, width along right."""
    c = np.asarray(centre, dtype=np.float64)
    f = forward * (length_m / 2)
    r = right * (width_m / 2)
    return np.array([c + f - r, c + f + r, c - f + r, c - f - r])


def _coverage(polys_px: list[np.ndarray], shape_hw: tuple[int, int]):
    """Fraction of each pixel covered by the union of polygons (pixel coordinates).

    Returns (x0, y0, coverage float32) for the window of the frame the polygons touch, clipped to
    the frame, or None when they miss it.
    """
    allp = np.concatenate(polys_px)
    x0 = max(int(math.floor(allp[:, 0].min())) - 1, 0)
    y0 = max(int(math.floor(allp[:, 1].min())) - 1, 0)
    x1 = min(int(math.ceil(allp[:, 0].max())) + 2, shape_hw[1])
    y1 = min(int(math.ceil(allp[:, 1].max())) + 2, shape_hw[0])
    if x1 <= x0 or y1 <= y0:
        return None
    s = _SUPERSAMPLE
    buf = np.zeros(((y1 - y0) * s, (x1 - x0) * s), np.uint8)
    # Sub-pixel k of pixel u has its centre at u - 0.5 + (k + 0.5) / s, so pixel position p maps to
    # s * (p - origin) + (s - 1) / 2 in the supersampled buffer.
    scale = float(1 << _SHIFT_BITS)
    pts = [np.round(((p - (x0, y0)) * s + (s - 1) / 2) * scale).astype(np.int32) for p in polys_px]
    # Anti-aliased edges in the supersampled buffer too: without, an edge moves in steps of 1/8 px.
    cv2.fillPoly(buf, pts, 255, lineType=cv2.LINE_AA, shift=_SHIFT_BITS)
    small = cv2.resize(buf, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return x0, y0, small.astype(np.float32) * (1.0 / 255.0)


def _paint(img: np.ndarray, polys_px: list[np.ndarray], bgr) -> None:
    """Blend a colour into img (float32, H x W x 3) over the polygons' coverage, in place."""
    got = _coverage(polys_px, img.shape[:2])
    if got is None:
        return
    x0, y0, cov = got
    h, w = cov.shape
    roi = img[y0:y0 + h, x0:x0 + w]
    c = cov[:, :, None]
    roi *= 1.0 - c
    roi += c * np.asarray(bgr, dtype=np.float32)


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


class Renderer:
    """Draws frames of one camera; caches the static part of the last scene it drew.

    render(scene, rng) -> 640 x 480 BGR uint8 (the camera's size). rng (numpy Generator) chooses
    the frame's noise; the floor's pattern comes from `seed` and stays put from frame to frame.
    """

    def __init__(self, look: RoverLook | None = None, camera: Camera | None = None, seed: int = 0):
        self.look = look or RoverLook()
        self.camera = camera or Camera()
        self.seed = seed
        self._static_key = None
        self._albedo: np.ndarray | None = None      # float32 H x W x 3, unlit
        self._lit: np.ndarray | None = None         # uint8 H x W x 3, lit, no rover, no noise
        self._light = self.camera.lighting.factor(self.camera.width_px, self.camera.height_px)
        self._noise: np.ndarray | None = None

    # -- static part -------------------------------------------------------------------------------

    def _floor(self, mapping: Calibration, arena_w_m: float, arena_h_m: float) -> np.ndarray:
        cam, look = self.camera, self.look
        rng = np.random.default_rng(self.seed)
        uu, vv = np.meshgrid(np.arange(cam.width_px, dtype=np.float64), np.arange(cam.height_px, dtype=np.float64))
        xy = mapping.to_arena(np.stack([uu, vv], axis=-1))
        x, y = xy[..., 0], xy[..., 1]
        tile_m = 0.30
        tx, ty = np.floor(x / tile_m), np.floor(y / tile_m)
        shade = rng.normal(0.0, 5.0, size=(64, 64))
        tile_shade = shade[(tx.astype(np.int64) % 64), (ty.astype(np.int64) % 64)]
        # Grout: a soft line about 5 mm wide along the tile edges.
        dx = np.abs(x / tile_m - np.round(x / tile_m)) * tile_m
        dy = np.abs(y / tile_m - np.round(y / tile_m)) * tile_m
        grout = np.exp(-(np.minimum(dx, dy) / 0.0035) ** 2)
        floor = np.asarray(look.floor_bgr, np.float64)
        gr = np.asarray(look.grout_bgr, np.float64)
        img = floor[None, None, :] + tile_shade[..., None]
        img = img * (1 - grout[..., None]) + gr[None, None, :] * grout[..., None]
        mottle = cv2.resize(rng.normal(0.0, 6.0, size=(7, 9)).astype(np.float32), (cam.width_px, cam.height_px),
                            interpolation=cv2.INTER_CUBIC)
        grain = rng.normal(0.0, 2.0, size=(cam.height_px, cam.width_px)).astype(np.float32)
        img = img + (mottle + grain)[..., None]
        inside = (x >= 0) & (x <= arena_w_m) & (y >= 0) & (y <= arena_h_m)
        img[~inside] = np.asarray(look.outside_bgr, np.float64)
        return img.astype(np.float32)

    def _draw_tag(self, img: np.ndarray, mapping: Calibration, centre, heading_deg: float, tag_id: int) -> None:
        look = self.look
        pattern = _tag_pattern(look.aruco_dictionary, tag_id)
        cells = pattern.shape[0]
        cell_m = look.aruco_size_m / cells
        fwd, right = _forward_right(heading_deg)
        c = np.asarray(centre, dtype=np.float64)
        # A white quiet zone one cell wide, so the black border stands out from the body or floor.
        quiet = _rect(c, fwd, right, look.aruco_size_m + 2 * cell_m, look.aruco_size_m + 2 * cell_m)
        _paint(img, [mapping.to_pixels(quiet)], (235, 235, 235))
        polys = []
        half = look.aruco_size_m / 2
        for r in range(cells):
            for k in range(cells):
                if pattern[r, k]:
                    a0, a1 = -half + k * cell_m, -half + (k + 1) * cell_m      # along right
                    b1, b0 = half - r * cell_m, half - (r + 1) * cell_m        # along forward
                    quad = np.array([c + a0 * right + b1 * fwd, c + a1 * right + b1 * fwd,
                                     c + a1 * right + b0 * fwd, c + a0 * right + b0 * fwd])
                    polys.append(mapping.to_pixels(quad))
        _paint(img, polys, (20, 20, 20))

    def _draw_square(self, img, mapping, centre, size_m: float, bgr, heading_deg: float = 0.0) -> None:
        fwd, right = _forward_right(heading_deg)
        _paint(img, [mapping.to_pixels(_rect(centre, fwd, right, size_m, size_m))], bgr)

    def _build_static(self, scene: Scene) -> None:
        cam, look = self.camera, self.look
        mapping = cam.mapping(scene.arena_w_m, scene.arena_h_m)
        img = self._floor(mapping, scene.arena_w_m, scene.arena_h_m)
        up, right = _forward_right(0.0)
        for cx, cy, w, h in scene.obstacles:
            _paint(img, [mapping.to_pixels(_rect((cx, cy), up, right, h, w))], look.obstacle_rim_bgr)
            rim = min(0.012, w / 4, h / 4)
            _paint(img, [mapping.to_pixels(_rect((cx, cy), up, right, h - 2 * rim, w - 2 * rim))], look.obstacle_bgr)
        squares = {"front": (look.marker_size_m, look.front_bgr), "back": (look.marker_size_m, look.back_bgr),
                   "target": (look.target_size_m, look.target_bgr)}
        for kind, x, y in scene.decoys:
            if isinstance(kind, int):
                self._draw_tag(img, mapping, (x, y), 0.0, kind)
            elif kind in squares:
                size, bgr = squares[kind]
                self._draw_square(img, mapping, (x, y), size, bgr)
            else:
                raise ValueError(f"decoy kind {kind!r}: expected 'front', 'back', 'target' or a tag id")
        if scene.target is not None:
            if scene.marker_kind == "aruco":
                self._draw_tag(img, mapping, scene.target, 0.0, look.target_tag_id)
            else:
                self._draw_square(img, mapping, scene.target, look.target_size_m, look.target_bgr)
        self._albedo = img
        lit = img * self._light[..., None]
        self._lit = np.clip(np.rint(lit), 0, 255).astype(np.uint8)

    # -- per frame ---------------------------------------------------------------------------------

    def _rover_body(self, scene: Scene, mapping: Calibration):
        """The rover's centre (arena), heading, forward and right unit vectors, and body corners (pixels)."""
        look = self.look
        x, y, heading = scene.rover  # type: ignore[misc]
        fwd, right = _forward_right(heading)
        c = np.array([x, y], dtype=np.float64)
        body = _rect(c + look.body_offset_m * fwd, fwd, right, look.body_length_m, look.body_width_m)
        return c, heading, fwd, right, mapping.to_pixels(body)

    def render(self, scene: Scene, rng: np.random.Generator) -> np.ndarray:
        if scene.marker_kind not in ("colour", "aruco"):
            raise ValueError(f"marker_kind {scene.marker_kind!r}: expected 'colour' or 'aruco'")
        cam, look = self.camera, self.look
        key = (scene.arena_w_m, scene.arena_h_m, scene.obstacles, scene.target, scene.marker_kind, scene.decoys)
        if key != self._static_key:
            self._build_static(scene)
            self._static_key = key
        assert self._lit is not None and self._albedo is not None
        frame = self._lit.copy()
        if scene.rover is not None:
            self._draw_rover(frame, scene, cam.mapping(scene.arena_w_m, scene.arena_h_m))
        if cam.noise_sigma > 0:
            frame = self._add_noise(frame, rng)
        return frame

    def _draw_rover(self, frame: np.ndarray, scene: Scene, mapping: Calibration) -> None:
        look = self.look
        c, heading, fwd, right, body_px = self._rover_body(scene, mapping)
        # Work on an unlit patch around the rover, then light it and put it into the frame.
        extent = max(look.body_length_m / 2 + abs(look.body_offset_m), look.body_width_m / 2,
                     look.aruco_size_m * 0.75) + 0.01
        box = mapping.to_pixels(_rect(c, fwd, right, 2 * extent, 2 * extent))
        h_px, w_px = frame.shape[:2]
        x0 = max(int(math.floor(box[:, 0].min())) - 2, 0)
        y0 = max(int(math.floor(box[:, 1].min())) - 2, 0)
        x1 = min(int(math.ceil(box[:, 0].max())) + 3, w_px)
        y1 = min(int(math.ceil(box[:, 1].max())) + 3, h_px)
        if x1 <= x0 or y1 <= y0:
            return
        patch = self._albedo[y0:y1, x0:x1].copy()   # type: ignore[index]
        origin = np.array([x0, y0], dtype=np.float64)
        shifted = _ShiftedMapping(mapping, origin)
        _paint(patch, [body_px - origin], look.body_bgr)
        if scene.marker_kind == "aruco":
            if "tag" not in scene.hidden:
                self._draw_tag(patch, shifted, c, heading, look.rover_tag_id)  # type: ignore[arg-type]
        else:
            d = look.marker_distance_m
            back = c - look.centre_fraction * d * fwd
            front = back + d * fwd
            for name, centre, bgr in (("back", back, look.back_bgr), ("front", front, look.front_bgr)):
                if name not in scene.hidden:
                    self._draw_square(patch, shifted, centre, look.marker_size_m, bgr, heading)
        lit = patch * self._light[y0:y1, x0:x1, None]
        frame[y0:y1, x0:x1] = np.clip(np.rint(lit), 0, 255).astype(np.uint8)

    def _add_noise(self, frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Gaussian sensor noise from a bank drawn once, cut at a random offset each frame. Kept as
        its positive and negative parts in uint8, so two saturating byte operations apply it."""
        h, w = frame.shape[:2]
        if self._noise is None:
            bank_rng = np.random.default_rng((self.seed, 0x5E4))
            bank = np.rint(bank_rng.normal(0.0, self.camera.noise_sigma,
                                           size=(h + _NOISE_PAD, w + _NOISE_PAD, 3)))
            self._noise = (np.clip(bank, 0, 255).astype(np.uint8), np.clip(-bank, 0, 255).astype(np.uint8))
        oy, ox = rng.integers(0, _NOISE_PAD + 1, size=2)
        plus, minus = self._noise
        frame = cv2.add(frame, plus[oy:oy + h, ox:ox + w])
        return cv2.subtract(frame, minus[oy:oy + h, ox:ox + w])


class _ShiftedMapping:
    """A mapping whose pixel coordinates are relative to a patch's corner."""

    def __init__(self, mapping: Calibration, origin_px: np.ndarray):
        self._m, self._o = mapping, origin_px

    def to_pixels(self, pts_m) -> np.ndarray:
        return self._m.to_pixels(pts_m) - self._o


_RENDERERS: dict[tuple, Renderer] = {}


def render_frame(scene: Scene, rng: np.random.Generator, *, look: RoverLook | None = None,
                 camera: Camera | None = None, seed: int = 0) -> np.ndarray:
    """One BGR uint8 frame (camera.height_px x camera.width_px x 3, 480 x 640 by default) of a scene.

    A convenience over `Renderer`: keeps one renderer per (look, camera, seed), so a loop drawing the
    same arena re-uses its floor. rng chooses the sensor noise.
    """
    look = look or RoverLook()
    camera = camera or Camera()
    key = (look, camera, seed)
    r = _RENDERERS.get(key)
    if r is None:
        if len(_RENDERERS) > 16:
            _RENDERERS.clear()
        r = _RENDERERS[key] = Renderer(look, camera, seed)
    return r.render(scene, rng)
