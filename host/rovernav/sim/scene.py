"""What the simulated overhead camera looks at and how: the scene in the arena at one instant, the
rover's and markers' sizes and colours, the light on the floor and the camera itself. The renderer
(rovernav.sim.camera) draws frames from these.

Conventions are the vision package's: arena metres from the bottom-left corner, x right, y up;
heading 0 = +y (up the image), clockwise positive, degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..vehicle_gen import BODY_LENGTH_MM, BODY_WIDTH_MM, DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from ..vision.calibration import Calibration
from ..vision.config import ARUCO_SIZE_M, MARKER_DISTANCE_M, ROVER_CENTRE_FRACTION, VisionConfig

BGR = tuple[int, int, int]


@dataclass(frozen=True)
class Scene:
    """What is in the arena at one instant.

    obstacles: boxes as (centre x, centre y, width, height) in metres, axis-aligned.
    walls: thick segments as (x0, y0, x1, y1, thickness) in metres (square ends, flush with the points).
    posts: round posts as (centre x, centre y, radius) in metres.
    rover: (x_m, y_m, heading_deg) of the rover centre, or None for an empty arena.
    target: (x_m, y_m) or None.
    marker_kind: "colour" (orange front, green back, yellow target squares) or "aruco" (tags).
    hidden: rover markers left undrawn, to imitate occlusion or a lost sticker: "front", "back"
        (colour squares) or "tag" (the rover's ArUco tag).
    decoys: extra markers lying on the floor, each (kind, x_m, y_m) with kind "front", "back" or
        "target" (a colour square like that marker) or an int (an ArUco tag with that id).
    fleet: more rovers, each (x_m, y_m, heading_deg, tag_id): drawn like the rover, with its own
        ArUco tag (marker_kind "aruco" only: a fleet is told apart by its tags).
    """

    arena_w_m: float = DEFAULT_ARENA_WIDTH_MM / 1000.0  # protocol/vehicle.toml
    arena_h_m: float = DEFAULT_ARENA_HEIGHT_MM / 1000.0
    obstacles: tuple[tuple[float, float, float, float], ...] = ()
    walls: tuple[tuple[float, float, float, float, float], ...] = ()
    posts: tuple[tuple[float, float, float], ...] = ()
    rover: tuple[float, float, float] | None = None
    target: tuple[float, float] | None = None
    marker_kind: str = "colour"
    hidden: frozenset[str] = frozenset()
    decoys: tuple[tuple[str | int, float, float], ...] = ()
    fleet: tuple[tuple[float, float, float, int], ...] = ()

    @classmethod
    def of_scenario(cls, scenario, marker_kind: str, decoys: tuple = ()) -> Scene:
        """The scenario's arena, boxes, walls, posts and target, with no rover yet."""
        return cls(
            arena_w_m=scenario.arena.width_m,
            arena_h_m=scenario.arena.height_m,
            obstacles=tuple((o.x_m, o.y_m, o.w_m, o.h_m) for o in scenario.obstacles),
            walls=tuple((w.x0_m, w.y0_m, w.x1_m, w.y1_m, w.thickness_m) for w in scenario.walls),
            posts=tuple((p.x_m, p.y_m, p.radius_m) for p in scenario.posts),
            target=(scenario.target.x_m, scenario.target.y_m),
            marker_kind=marker_kind,
            decoys=decoys,
        )


@dataclass(frozen=True)
class RoverLook:
    """Sizes (metres) and colours (BGR) of what is drawn.

    The colour squares sit on the rover's centre line so that the rover centre is
    back + centre_fraction * (front - back), the rule the locator uses, with the squares'
    centres marker_distance_m apart. The body's centre is body_offset_m ahead of the rover centre.
    The rover's ArUco tag is centred on the rover centre, its top edge facing forward.
    """

    body_length_m: float = BODY_LENGTH_MM / 1000.0  # protocol/vehicle.toml
    body_width_m: float = BODY_WIDTH_MM / 1000.0
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
    front_bgr: BGR = (30, 110, 235)  # orange: OpenCV H 12, inside Table 4.1's 5-22
    back_bgr: BGR = (70, 175, 45)  # green: H 66, inside 55-80
    target_bgr: BGR = (40, 215, 220)  # yellow: H 29, inside 25-35
    obstacle_bgr: BGR = (118, 124, 130)  # warm grey, S about 24: below every marker's S floor
    obstacle_rim_bgr: BGR = (92, 96, 100)
    floor_bgr: BGR = (150, 156, 162)
    grout_bgr: BGR = (118, 121, 124)
    outside_bgr: BGR = (64, 64, 64)  # beyond the arena, when an oblique camera sees past it

    @classmethod
    def for_vision(cls, config: VisionConfig, **overrides) -> RoverLook:
        """A look that matches a VisionConfig's geometry and ArUco settings."""
        kw = dict(
            marker_distance_m=config.marker_distance_m,
            centre_fraction=config.rover_centre_fraction,
            aruco_size_m=config.aruco.size_m,
            aruco_dictionary=config.aruco.dictionary,
            rover_tag_id=config.aruco.rover_id,
            target_tag_id=config.aruco.target_id,
        )
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
    def uniform(cls) -> Lighting:
        return cls(level=1.0, gradient=0.0, vignette=0.0)

    @classmethod
    def random(cls, rng: np.random.Generator) -> Lighting:
        """A plausible uneven light: between about 0.5 and 1.2 across the frame."""
        return cls(
            level=float(rng.uniform(0.9, 1.05)),
            gradient=float(rng.uniform(0.05, 0.25)),
            gradient_angle_deg=float(rng.uniform(0.0, 360.0)),
            vignette=float(rng.uniform(0.1, 0.35)),
        )

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
