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

Speed (benchmarks/bench_render.py): the floor, obstacles and target are drawn and lit once per
scene and kept, with a few noisy copies; a frame then costs a copy of one of those, the rover drawn
in a window round its body, and fresh noise (a random window into a bank of Gaussian noise drawn
once) over the rover and the markers: about 0.25 ms for 640 x 480 on this project's 2-core
machine, where drawing the rover with the whole frame's noise took 0.9 ms.

The scene, the rover's look, the light and the camera that a frame is drawn from are described in
rovernav.sim.scene, the drawing primitives (shapes, coverage, painting, lighting up) are in
rovernav.sim.raster; this module draws, and re-exports the description's names.

Conventions are the vision package's: arena metres from the bottom-left corner, x right, y up;
heading 0 = +y (up the image), clockwise positive, degrees.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..vision.calibration import Calibration
from .raster import _forward_right, _group, _light_up, _paint, _rect, _rect_local, _Shape, _tag_pattern, _window
from .scene import BGR, Camera, Lighting, RoverLook, Scene

__all__ = ["BGR", "Camera", "Lighting", "Renderer", "RoverLook", "Scene", "render_frame"]

_NOISE_PAD = 48  # the noise bank is this much larger than a frame on each axis
_NOISE_POOL = 8  # noisy copies of the lit arena kept for the floor's noise (see Renderer)
_FRESH_MARGIN_PX = 8  # fresh noise this far round every marker and the rover's body


class Renderer:
    """Draws frames of one camera; caches the static part of the last scene it drew.

    render(scene, rng) -> 640 x 480 BGR uint8 (the camera's size). rng (numpy Generator) chooses
    the frame's noise; the floor's pattern comes from `seed` and stays put from frame to frame.

    What a frame costs (see benchmarks/bench_render.py): the arena without the rover (floor,
    obstacles, target, decoys, lit) is drawn once per scene geometry and kept; a frame copies it and
    draws only the rover, in a window round its body, from the kept unlit floor. The pixels are the
    ones `reference_frame` computes by drawing everything on one image (a test checks that they are
    equal, bit for bit).

    Noise: Gaussian, standard deviation camera.noise_sigma, rounded, as a random window into a
    bank drawn once from `seed`. Round everything the locator measures (the rover and a margin of
    8 px round it, which holds the locator's refine windows round its markers; each static marker
    with the same margin) the noise is a fresh window of the bank each frame, chosen by rng. Over
    the rest (floor and obstacles, where no marker colour can appear) it comes from one of a few
    noisy copies of the lit arena made once, chosen by the same draw: the same statistics pixel by
    pixel, but re-used, which saves two full-frame operations a frame.
    """

    def __init__(self, look: RoverLook | None = None, camera: Camera | None = None, seed: int = 0):
        self.look = look or RoverLook()
        self.camera = camera or Camera()
        self.seed = seed
        self._shape_hw = (self.camera.height_px, self.camera.width_px)
        self._light = self.camera.lighting.factor(self.camera.width_px, self.camera.height_px)
        self._floors: dict[tuple[float, float], np.ndarray] = {}
        self._mappings: dict[tuple[float, float], Calibration] = {}
        self._templates: dict[tuple, tuple[np.ndarray, list[tuple[int, BGR]]]] = {}
        self._static_key = None
        self._albedo: np.ndarray | None = None  # float32 3 x H x W (planar), unlit, no rover
        self._lit: np.ndarray | None = None  # uint8 H x W x 3, lit, no rover, no noise
        self._fresh: list[tuple[int, int, int, int]] = []  # windows round the static markers
        self._noise: tuple[np.ndarray, np.ndarray] | None = None
        self._pool_offsets: np.ndarray | None = None
        self._pool: list[np.ndarray | None] = []

    # -- what is drawn -----------------------------------------------------------------------------

    def _mapping(self, arena_w_m: float, arena_h_m: float) -> Calibration:
        key = (arena_w_m, arena_h_m)
        got = self._mappings.get(key)
        if got is None:
            if len(self._mappings) > 4:
                self._mappings.clear()
            got = self._mappings[key] = self.camera.mapping(arena_w_m, arena_h_m)
        return got

    def _floor(self, mapping: Calibration, arena_w_m: float, arena_h_m: float) -> np.ndarray:
        """The unlit floor (float32, planar 3 x H x W); the same for every scene of one arena size."""
        key = (arena_w_m, arena_h_m)
        if key not in self._floors:
            self._floors.clear()
            self._floors[key] = self._draw_floor(mapping, arena_w_m, arena_h_m)
        return self._floors[key]

    def _draw_floor(self, mapping: Calibration, arena_w_m: float, arena_h_m: float) -> np.ndarray:
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
        grout = np.exp(-((np.minimum(dx, dy) / 0.0035) ** 2))
        floor = np.asarray(look.floor_bgr, np.float64)
        gr = np.asarray(look.grout_bgr, np.float64)
        img = floor[None, None, :] + tile_shade[..., None]
        img = img * (1 - grout[..., None]) + gr[None, None, :] * grout[..., None]
        mottle = cv2.resize(
            rng.normal(0.0, 6.0, size=(7, 9)).astype(np.float32),
            (cam.width_px, cam.height_px),
            interpolation=cv2.INTER_CUBIC,
        )
        grain = rng.normal(0.0, 2.0, size=(cam.height_px, cam.width_px)).astype(np.float32)
        img = img + (mottle + grain)[..., None]
        inside = (x >= 0) & (x <= arena_w_m) & (y >= 0) & (y <= arena_h_m)
        img[~inside] = np.asarray(look.outside_bgr, np.float64)
        return np.ascontiguousarray(img.astype(np.float32).transpose(2, 0, 1))

    # A template: a drawing in a marker's or the rover's own frame, as quadrilaterals' corners
    # (N x 4 x 2: metres along its forward, metres along its right) and how they are painted:
    # [(number of consecutive quadrilaterals filled together, colour), ...] in drawing order.

    def _template(self, key: tuple) -> tuple[np.ndarray, list[tuple[int, BGR]]]:
        got = self._templates.get(key)
        if got is None:
            got = self._templates[key] = self._make_template(key)
        return got

    def _make_template(self, key: tuple) -> tuple[np.ndarray, list[tuple[int, BGR]]]:
        look = self.look
        what = key[0]
        if what == "square":
            _, size_m, bgr = key
            return _rect_local(0.0, size_m, size_m)[None], [(1, bgr)]
        if what == "tag":
            pattern = _tag_pattern(look.aruco_dictionary, key[1])
            cells = pattern.shape[0]
            cell_m = look.aruco_size_m / cells
            # A white quiet zone one cell wide, so the black border stands out from the body or floor.
            quads = [_rect_local(0.0, look.aruco_size_m + 2 * cell_m, look.aruco_size_m + 2 * cell_m)]
            half = look.aruco_size_m / 2
            for r in range(cells):
                for k in range(cells):
                    if pattern[r, k]:
                        a0, a1 = -half + k * cell_m, -half + (k + 1) * cell_m  # along right
                        b1, b0 = half - r * cell_m, half - (r + 1) * cell_m  # along forward
                        quads.append(np.array([(b1, a0), (b1, a1), (b0, a1), (b0, a0)]))
            return np.array(quads), [(1, (235, 235, 235)), (len(quads) - 1, (20, 20, 20))]
        # The rover: its body, then its colour squares (back, front) or its tag. A fleet's other
        # rovers: ("rover", "aruco", hidden, their tag id; below 0: no tag).
        _, marker_kind, hidden, *other = key
        tag_id = other[0] if other else look.rover_tag_id
        quads = [_rect_local(look.body_offset_m, look.body_length_m, look.body_width_m)]
        groups: list[tuple[int, BGR]] = [(1, look.body_bgr)]
        if marker_kind == "aruco":
            if "tag" not in hidden and tag_id >= 0:
                tag_quads, tag_groups = self._template(("tag", tag_id))
                quads += list(tag_quads)
                groups += tag_groups
        else:
            back = -look.centre_fraction * look.marker_distance_m
            for name, u, bgr in (
                ("back", back, look.back_bgr),
                ("front", back + look.marker_distance_m, look.front_bgr),
            ):
                if name not in hidden:
                    quads.append(_rect_local(u, look.marker_size_m, look.marker_size_m))
                    groups.append((1, bgr))
        return np.array(quads), groups

    def _place(self, mapping: Calibration, key: tuple, centre, heading_deg: float) -> list[_Shape]:
        """A template put at centre (arena metres) facing heading_deg: shapes in pixels."""
        quads, groups = self._template(key)
        return _group(self._corners(mapping, quads, centre, heading_deg), groups)

    @staticmethod
    def _corners(mapping: Calibration, quads: np.ndarray, centre, heading_deg: float) -> np.ndarray:
        fwd, right = _forward_right(heading_deg)
        return mapping.to_pixels(np.asarray(centre, dtype=np.float64) + quads @ np.array([fwd, right]))

    def _static_shapes(self, scene: Scene, mapping: Calibration) -> tuple[list[_Shape], list[_Shape]]:
        """What does not move, in drawing order: (obstacles, markers: decoys then the target)."""
        look = self.look
        up, right = _forward_right(0.0)
        boxes: list[_Shape] = []
        for cx, cy, w, h in scene.obstacles:
            boxes.append(([mapping.to_pixels(_rect((cx, cy), up, right, h, w))], look.obstacle_rim_bgr))
            rim = min(0.012, w / 4, h / 4)
            boxes.append(([mapping.to_pixels(_rect((cx, cy), up, right, h - 2 * rim, w - 2 * rim))], look.obstacle_bgr))
        for x0, y0, x1, y1, t in scene.walls:
            length = math.hypot(x1 - x0, y1 - y0)
            fwd = np.array([(x1 - x0) / length, (y1 - y0) / length])
            side = np.array([fwd[1], -fwd[0]])
            centre = ((x0 + x1) / 2, (y0 + y1) / 2)
            boxes.append(([mapping.to_pixels(_rect(centre, fwd, side, length, t))], look.obstacle_rim_bgr))
            rim = min(0.012, length / 4, t / 4)
            boxes.append(
                ([mapping.to_pixels(_rect(centre, fwd, side, length - 2 * rim, t - 2 * rim))], look.obstacle_bgr)
            )
        for cx, cy, r in scene.posts:
            a = np.linspace(0.0, 2 * math.pi, 24, endpoint=False)
            rim = min(0.012, r / 4)
            for radius, colour in ((r, look.obstacle_rim_bgr), (r - rim, look.obstacle_bgr)):
                ring = np.stack([cx + radius * np.sin(a), cy + radius * np.cos(a)], axis=1)
                boxes.append(([mapping.to_pixels(ring)], colour))
        squares = {
            "front": (look.marker_size_m, look.front_bgr),
            "back": (look.marker_size_m, look.back_bgr),
            "target": (look.target_size_m, look.target_bgr),
        }
        markers: list[_Shape] = []
        for kind, x, y in scene.decoys:
            if isinstance(kind, int):
                markers += self._place(mapping, ("tag", kind), (x, y), 0.0)
            elif kind in squares:
                markers += self._place(mapping, ("square", *squares[kind]), (x, y), 0.0)
            else:
                raise ValueError(f"decoy kind {kind!r}: expected 'front', 'back', 'target' or a tag id")
        if scene.target is not None:
            if scene.marker_kind == "aruco":
                markers += self._place(mapping, ("tag", look.target_tag_id), scene.target, 0.0)
            else:
                markers += self._place(mapping, ("square", look.target_size_m, look.target_bgr), scene.target, 0.0)
        return boxes, markers

    @staticmethod
    def _rovers(scene: Scene) -> list[tuple[tuple[float, float, float], tuple]]:
        """Every rover in drawing order, (pose, template key): the rover, then the fleet's."""
        out = [] if scene.rover is None else [(scene.rover, ("rover", scene.marker_kind, scene.hidden))]
        if scene.fleet and scene.marker_kind != "aruco":
            raise ValueError("a fleet's rovers are told apart by their ArUco tags: marker_kind 'aruco'")
        out += [((x, y, h), ("rover", "aruco", scene.hidden, int(tag))) for x, y, h, tag in scene.fleet]
        return out

    def _rover_shapes(self, scene: Scene, mapping: Calibration) -> list[_Shape]:
        """The rovers in drawing order: each one's body, then its colour squares or its tag."""
        shapes: list[_Shape] = []
        for (x, y, heading), key in self._rovers(scene):
            shapes += self._place(mapping, key, (x, y), heading)
        return shapes

    def _static_albedo(self, scene: Scene, mapping: Calibration) -> tuple[np.ndarray, list[tuple[int, int, int, int]]]:
        """The unlit arena without the rover, and the windows round its markers."""
        img = self._floor(mapping, scene.arena_w_m, scene.arena_h_m).copy()
        boxes, markers = self._static_shapes(scene, mapping)
        for polys, bgr in boxes + markers:
            _paint(img, polys, bgr)
        windows = [_window(polys, _FRESH_MARGIN_PX, self._shape_hw) for polys, _ in markers]
        return img, [w for w in windows if w is not None]

    def reference_frame(self, scene: Scene) -> np.ndarray:
        """The scene without noise, drawn the plain way: everything static and the rover painted on
        one full-frame copy of the floor (a function of the arena's size and `seed` alone), then
        lit. A few milliseconds; `render` gives the same pixels (with noise_sigma 0, the same
        frame) from its caches and a window round the rover."""
        self._check(scene)
        mapping = self.camera.mapping(scene.arena_w_m, scene.arena_h_m)
        img = self._floor(mapping, scene.arena_w_m, scene.arena_h_m).copy()
        boxes, markers = self._static_shapes(scene, mapping)
        shapes = boxes + markers + self._rover_shapes(scene, mapping)
        for polys, bgr in shapes:
            _paint(img, polys, bgr)
        return _light_up(img, self._light)

    # -- per frame ---------------------------------------------------------------------------------

    @staticmethod
    def _check(scene: Scene) -> None:
        if scene.marker_kind not in ("colour", "aruco"):
            raise ValueError(f"marker_kind {scene.marker_kind!r}: expected 'colour' or 'aruco'")

    def noise_offsets(self, rng: np.random.Generator) -> tuple[int, int] | None:
        """The frame's draw from rng: where in the noise bank its fresh noise comes from (row,
        column), or None for a camera without noise (which draws nothing)."""
        if self.camera.noise_sigma <= 0:
            return None
        oy, ox = (int(v) for v in rng.integers(0, _NOISE_PAD + 1, size=2))
        return oy, ox

    def render(self, scene: Scene, rng: np.random.Generator) -> np.ndarray:
        """One frame of the scene; rng chooses its noise (one draw, `noise_offsets`)."""
        self._check(scene)
        return self.render_at(scene, self.noise_offsets(rng))

    def render_at(self, scene: Scene, offsets: tuple[int, int] | None) -> np.ndarray:
        """One frame of the scene with the noise `noise_offsets` chose: the same frame `render`
        draws from the rng that gave those offsets (the camera process draws this way)."""
        self._check(scene)
        cam = self.camera
        mapping = self._mapping(scene.arena_w_m, scene.arena_h_m)
        key = (
            scene.arena_w_m,
            scene.arena_h_m,
            scene.obstacles,
            scene.walls,
            scene.posts,
            scene.target,
            scene.marker_kind,
            scene.decoys,
        )
        if key != self._static_key:
            self._static_key = None
            self._albedo, self._fresh = self._static_albedo(scene, mapping)
            self._lit = _light_up(self._albedo, self._light)
            self._pool = [None] * _NOISE_POOL
            self._static_key = key
        lit = self._lit
        assert lit is not None
        rovers = self._rover_patches(scene, mapping)
        if cam.noise_sigma <= 0:
            frame = lit.copy()
            for (x0, y0, x1, y1), patch in rovers:
                frame[y0:y1, x0:x1] = patch
            return frame
        assert offsets is not None, "a camera with noise needs the frame's noise offsets"
        oy, ox = offsets
        frame = self._pool_frame((oy * (_NOISE_PAD + 1) + ox) % _NOISE_POOL).copy()
        plus, minus = self._noise  # type: ignore[misc]

        def fresh(x0: int, y0: int, x1: int, y1: int, clean: np.ndarray) -> None:
            out = frame[y0:y1, x0:x1]
            cv2.add(clean, plus[oy + y0 : oy + y1, ox + x0 : ox + x1], dst=out)
            cv2.subtract(out, minus[oy + y0 : oy + y1, ox + x0 : ox + x1], dst=out)

        for x0, y0, x1, y1 in self._fresh:
            fresh(x0, y0, x1, y1, lit[y0:y1, x0:x1])
        for (x0, y0, x1, y1), patch in rovers:
            m = _FRESH_MARGIN_PX
            h, w = self._shape_hw
            gx0, gy0, gx1, gy1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, w), min(y1 + m, h)
            fresh(gx0, gy0, gx1, gy1, lit[gy0:gy1, gx0:gx1])
            fresh(x0, y0, x1, y1, patch)
        return frame

    def _rover_patches(self, scene: Scene, mapping: Calibration) -> list:
        """The rovers drawn and lit in the smallest windows that hold them: [((x0, y0, x1, y1), uint8
        patch)], none for a rover out of sight; rovers whose windows overlap share one, painted in
        `_rovers`' order. Painted on the kept unlit floor exactly as `reference_frame` paints them
        on the whole frame (window-relative coordinates are exact)."""
        drawn = []  # [(box, [(corners, groups)])]: windows not overlapping, each with its rovers
        for (x, y, heading), key in self._rovers(scene):
            quads, groups = self._template(key)
            corners = self._corners(mapping, quads, (x, y), heading)
            box = _window([corners.reshape(-1, 2)], 0, self._shape_hw)
            if box is None:
                continue
            mine = [(corners, groups)]
            while True:  # a fleet's rovers side by side: one window, until none overlaps another
                others = [d for d in drawn if _overlap(d[0], box)]
                if not others:
                    break
                for other in others:
                    drawn.remove(other)
                    box = (
                        min(box[0], other[0][0]),
                        min(box[1], other[0][1]),
                        max(box[2], other[0][2]),
                        max(box[3], other[0][3]),
                    )
                mine = [r for other in others for r in other[1]] + mine  # in drawing order
            drawn.append((box, mine))
        out = []
        for (x0, y0, x1, y1), rovers in drawn:
            patch = self._albedo[:, y0:y1, x0:x1].copy()  # type: ignore[index]
            for corners, groups in rovers:
                for polys, bgr in _group(corners - (x0, y0), groups):
                    _paint(patch, polys, bgr)
            out.append(((x0, y0, x1, y1), _light_up(patch, self._light[y0:y1, x0:x1])))
        return out

    def _pool_frame(self, k: int) -> np.ndarray:
        """The k-th noisy copy of the lit arena (made when first asked for)."""
        if self._noise is None:
            h, w = self._shape_hw
            bank_rng = np.random.default_rng((self.seed, 0x5E4))
            bank = np.rint(bank_rng.normal(0.0, self.camera.noise_sigma, size=(h + _NOISE_PAD, w + _NOISE_PAD, 3)))
            self._noise = (np.clip(bank, 0, 255).astype(np.uint8), np.clip(-bank, 0, 255).astype(np.uint8))
            self._pool_offsets = bank_rng.integers(0, _NOISE_PAD + 1, size=(_NOISE_POOL, 2))
        got = self._pool[k]
        if got is None:
            h, w = self._shape_hw
            oy, ox = (int(v) for v in self._pool_offsets[k])  # type: ignore[index]
            plus, minus = self._noise
            got = self._pool[k] = cv2.subtract(
                cv2.add(self._lit, plus[oy : oy + h, ox : ox + w]), minus[oy : oy + h, ox : ox + w]
            )
        return got


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> bool:
    """Whether two pixel windows (x0, y0, x1, y1) share a pixel, or their fresh noise's margins do."""
    m = 2 * _FRESH_MARGIN_PX
    return a[0] < b[2] + m and b[0] < a[2] + m and a[1] < b[3] + m and b[1] < a[3] + m


_RENDERERS: dict[tuple, Renderer] = {}


def render_frame(
    scene: Scene,
    rng: np.random.Generator,
    *,
    look: RoverLook | None = None,
    camera: Camera | None = None,
    seed: int = 0,
) -> np.ndarray:
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
