"""A simulated set-up that is not the defaults: the markers' colours, the room's light, where the
camera looks from, and a rover whose motors and gyro differ from what the firmware assumes.

    setup = Setup.random(seed)                       # one of many, drawn from a seed
    frames = setup.calibration_frames(scenario, 3)   # what `rovernav calibrate camera` would see
    sim = Simulation(scenario, SimOptions(setup=setup, config=...))

Real set-ups differ in all of these, and a configuration made for one fails on another: the
default HSV ranges find no marker of another colour, and the default mapping (a camera looking
straight down whose frame spans the arena exactly) puts a tilted camera's rover in the wrong
place. The simulator's usual set-up is no Setup at all (SimOptions.setup None).

The arena has four ArUco corner tags (rovernav.vision.marks.CORNER_TAG_IDS), drawn in every
frame of a set-up's runs, as a real arena would keep them.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..vision.calibration import Calibration
from ..vision.marks import COLOUR_BANDS, CORNER_INSET_M, CORNER_TAG_IDS
from .camera import Lighting, Scene
from .plant import PlantConfig

if TYPE_CHECKING:
    from ..vision import VisionConfig

BGR = tuple[int, int, int]
FRAME_W_PX, FRAME_H_PX = 640, 480


def bgr_of(hue: float, sat: float, val: float) -> BGR:
    """An OpenCV HSV colour (H 0-179, S and V 0-255) as BGR."""
    px = np.array([[[round(hue), round(sat), round(val)]]], dtype=np.uint8)
    b, g, r = cv2.cvtColor(px, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


@dataclasses.dataclass(frozen=True)
class Setup:
    """front_bgr, back_bgr, target_bgr: the markers' colours; words: the colour word of each
    (what a user would say of the stickers: {"rover_front": "orange", ...}); lighting; corners_px:
    where the camera sees the arena's corners (bottom-left, bottom-right, top-right, top-left) in
    its 640 x 480 frame, None for straight down spanning the frame; plant; corner_tags: whether
    the four corner tags are drawn."""

    front_bgr: BGR = (30, 110, 235)
    back_bgr: BGR = (70, 175, 45)
    target_bgr: BGR = (40, 215, 220)
    words: tuple[tuple[str, str], ...] = (("rover_front", "orange"), ("rover_back", "green"), ("target", "yellow"))
    lighting: Lighting | None = None
    corners_px: tuple[tuple[float, float], ...] | None = None
    plant: PlantConfig = PlantConfig()
    corner_tags: bool = True
    seed: int | None = None

    @classmethod
    def random(cls, seed: int) -> Setup:
        """A set-up drawn from `seed`: three marker colours of distinct colour words, a light from
        0.55 to 1.15 of the usual with its gradient and vignette, a camera tilted up to about 20
        degrees and turned up to 8 (the arena filling 70-90 % of the frame), and motors and gyro
        off the firmware's figures (speed per PWM 0.8-1.25 x, the right motor 0.95-1.2 x the
        left, dead band 0.8-1.3 x, gyro bias left after calibration up to 0.15 deg/s, gyro scale
        0.97-1.03), and the sonar 70-130 mm ahead of the rover's centre (the configuration's default
        says 100)."""
        rng = np.random.default_rng([seed, 0x5E7])
        while True:  # three colours a user would call by different names, at least 15 hue units apart
            words = [str(w) for w in rng.choice(sorted(COLOUR_BANDS), size=3, replace=False)]
            hues = [rng.uniform(COLOUR_BANDS[w][0] + 2.5, COLOUR_BANDS[w][1] - 2.5) for w in words]
            if all(min(abs(a - b), 180 - abs(a - b)) >= 15 for a, b in itertools.combinations(hues, 2)):
                break
        colours = [bgr_of(h, rng.uniform(150, 240), rng.uniform(160, 235)) for h in hues]
        lighting = Lighting(
            level=float(rng.uniform(0.55, 1.15)),
            gradient=float(rng.uniform(0.05, 0.3)),
            gradient_angle_deg=float(rng.uniform(0.0, 360.0)),
            vignette=float(rng.uniform(0.1, 0.4)),
        )
        base = PlantConfig()
        plant = dataclasses.replace(
            base,
            mm_s_per_pwm=base.mm_s_per_pwm * float(rng.uniform(0.8, 1.25)),
            right_gain=float(rng.uniform(0.95, 1.2)),
            deadband_pwm=base.deadband_pwm * float(rng.uniform(0.8, 1.3)),
            gyro_bias_dps=float(rng.uniform(0.02, 0.15)),
        )
        corners = _tilted_corners(rng)
        # Drawn last, so that every draw before it is as it was before the gyro's scale was modelled.
        plant = dataclasses.replace(plant, gyro_scale=float(rng.uniform(0.97, 1.03)))
        # Then the sonar's place, last for the same reason.
        plant = dataclasses.replace(plant, sonar_offset_m=float(rng.uniform(0.07, 0.13)))
        return cls(
            front_bgr=colours[0],
            back_bgr=colours[1],
            target_bgr=colours[2],
            words=tuple(zip(("rover_front", "rover_back", "target"), words)),
            lighting=lighting,
            corners_px=corners,
            plant=plant,
            seed=seed,
        )

    def colour_words(self) -> dict[str, str]:
        return dict(self.words)

    def mapping(self, arena_w_m: float, arena_h_m: float) -> Calibration:
        if self.corners_px is None:
            return Calibration.straight_down(FRAME_W_PX, FRAME_H_PX, arena_w_m, arena_h_m)
        return Calibration.from_corners(self.corners_px, arena_w_m, arena_h_m)

    def decoys(self, arena_w_m: float, arena_h_m: float) -> tuple[tuple[int, float, float], ...]:
        """The corner tags, as the renderer's decoys (tag id, centre x, centre y)."""
        if not self.corner_tags:
            return ()
        d, w, h = CORNER_INSET_M, arena_w_m, arena_h_m
        return tuple(zip(CORNER_TAG_IDS, (d, w - d, w - d, d), (d, d, h - d, h - d)))

    def calibration_frames(self, scenario, count: int = 3, rng_seed: int = 0) -> list[np.ndarray]:
        """`count` frames of the scenario at its start (the rover at its start pose, the target in
        place), each with its own sensor noise: what a user would capture for calibration."""
        from .camera import Camera, Renderer, RoverLook

        w, h = scenario.arena.width_m, scenario.arena.height_m
        renderer = Renderer(
            RoverLook(front_bgr=self.front_bgr, back_bgr=self.back_bgr, target_bgr=self.target_bgr),
            Camera(calibration=self.mapping(w, h), lighting=self.lighting or Lighting()),
            seed=rng_seed,
        )
        s = scenario.start
        scene = Scene(
            arena_w_m=w,
            arena_h_m=h,
            obstacles=tuple((o.x_m, o.y_m, o.w_m, o.h_m) for o in scenario.obstacles),
            walls=tuple((q.x0_m, q.y0_m, q.x1_m, q.y1_m, q.thickness_m) for q in scenario.walls),
            posts=tuple((p.x_m, p.y_m, p.radius_m) for p in scenario.posts),
            rover=(s.x_m, s.y_m, s.heading_deg),
            target=(scenario.target.x_m, scenario.target.y_m),
            decoys=self.decoys(w, h),
        )
        rng = np.random.default_rng([rng_seed, 0xCA1])
        return [renderer.render(scene, rng) for _ in range(count)]


def _tilted_corners(rng: np.random.Generator) -> tuple[tuple[float, float], ...]:
    """Where a tilted, turned camera sees the arena's corners: a rectangle of the frame's 4:3 shape
    filling 70-90 % of it, its far edge shortened by up to 25 % (a tilt of about 20
    degrees), turned by up to 8 degrees and moved a little off centre; shrunk until every corner
    lies 12 pixels or more inside the frame."""
    fill, keystone = rng.uniform(0.7, 0.9), rng.uniform(0.0, 0.25)
    far_top = bool(rng.random() < 0.5)  # which edge is further from the camera
    turn = math.radians(rng.uniform(-8.0, 8.0))
    off_x, off_y = rng.uniform(-0.4, 0.4, size=2)
    while True:
        half_w, half_h = fill * FRAME_W_PX / 2, fill * FRAME_H_PX / 2
        pts = []
        for sx, sy in ((-1, 1), (1, 1), (1, -1), (-1, -1)):  # BL, BR, TR, TL (v grows downwards)
            far = (sy < 0) == far_top
            pts.append(
                (sx * half_w * ((1 - keystone) if far else 1.0), sy * half_h * ((1 - 0.3 * keystone) if far else 1.0))
            )
        cx = FRAME_W_PX / 2 + off_x * (FRAME_W_PX / 2 - half_w)
        cy = FRAME_H_PX / 2 + off_y * (FRAME_H_PX / 2 - half_h)
        c, s = math.cos(turn), math.sin(turn)
        out = tuple((float(cx + c * x - s * y), float(cy + s * x + c * y)) for x, y in pts)
        if all(12 <= u <= FRAME_W_PX - 13 and 12 <= v <= FRAME_H_PX - 13 for u, v in out):
            return out
        fill *= 0.97


def true_vision(setup: Setup, arena_w_m: float, arena_h_m: float) -> VisionConfig:
    """The settings a user who knew the set-up's truth would write: the true corners, and ranges
    round the markers' true hues (+-8), S and V down to 40. What calibration is measured against."""
    from ..vision import VisionConfig

    hsv = {}
    for role, bgr in (("rover_front", setup.front_bgr), ("rover_back", setup.back_bgr), ("target", setup.target_bgr)):
        h = int(cv2.cvtColor(np.uint8([[bgr]]), cv2.COLOR_BGR2HSV)[0, 0, 0])
        hsv[role] = [[max(0, h - 8), 40, 40], [min(179, h + 8), 255, 255]]
    corners = setup.corners_px or tuple(
        tuple(float(v) for v in p)
        for p in setup.mapping(arena_w_m, arena_h_m).to_pixels(
            np.array([[0.0, 0.0], [arena_w_m, 0.0], [arena_w_m, arena_h_m], [0.0, arena_h_m]])
        )
    )
    return VisionConfig.from_dict(
        {
            "hsv": hsv,
            "calibration": {"corners_px": [list(c) for c in corners], "width_m": arena_w_m, "height_m": arena_h_m},
        }
    )


def pose_errors(setup: Setup, vision, scenario, n: int = 12, seed: int = 0) -> list[tuple[float | None, float | None]]:
    """The locator with `vision` on n frames of the set-up with the rover at random poses:
    (position error [m], heading error [deg]) of each, (None, None) where it found no rover."""
    from ..vision import Locator
    from .camera import Camera, Renderer, RoverLook

    w, h = scenario.arena.width_m, scenario.arena.height_m
    rng = np.random.default_rng([seed, 0x905])
    renderer = Renderer(
        RoverLook(front_bgr=setup.front_bgr, back_bgr=setup.back_bgr, target_bgr=setup.target_bgr),
        Camera(calibration=setup.mapping(w, h), lighting=setup.lighting or Lighting()),
        seed=seed,
    )
    locator = Locator(vision, w, h)
    out: list[tuple[float | None, float | None]] = []
    for _ in range(n):
        x, y, hd = rng.uniform(0.3, w - 0.3), rng.uniform(0.3, h - 0.3), rng.uniform(0.0, 360.0)
        scene = Scene(
            arena_w_m=w,
            arena_h_m=h,
            rover=(x, y, hd),
            target=(scenario.target.x_m, scenario.target.y_m),
            decoys=setup.decoys(w, h),
        )
        locator.reset()
        d = locator.locate(renderer.render(scene, rng))
        if d.rover is None:
            out.append((None, None))
        else:
            out.append(
                (math.hypot(d.rover.x_m - x, d.rover.y_m - y), (d.rover.heading_deg - hd + 180.0) % 360.0 - 180.0)
            )
    return out
