"""Issue 30's "who is who": several rovers under one camera, each by its own ArUco tag. The
renderer draws them (pixel for pixel as its plain drawing does, side by side too) and the
FleetLocator finds every one, never one for another, and says which it lost and why."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.vision import VisionConfig
from rovernav.vision.config import ArucoConfig
from rovernav.vision.fleet import FleetLocator

TAGS = {1: 1, 2: 3, 3: 4}  # rover id -> tag id (the target's tag is 2)
ARENA = Scene(
    arena_w_m=2.36,
    arena_h_m=1.75,
    obstacles=((1.2, 0.9, 0.2, 0.3),),
    target=(2.1, 1.5),
    marker_kind="aruco",
)


def _config() -> VisionConfig:
    return VisionConfig(markers="aruco", aruco=ArucoConfig(rover_id=1, target_id=2))


def _scene(poses: dict[int, tuple[float, float, float]], tags: dict[int, int] = TAGS) -> Scene:
    """Rover 1 as the scene's rover (tag 1), the others as its fleet."""
    fleet = tuple((*poses[r], tags[r]) for r in sorted(poses) if r != 1)
    return dataclasses.replace(ARENA, rover=poses.get(1), fleet=fleet)


def _angle_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def test_every_rover_is_found_as_itself_frame_after_frame():
    rng = np.random.default_rng(30)
    renderer = Renderer(RoverLook(), Camera(lighting=Lighting.random(rng), noise_sigma=3.0), seed=7)
    locator = FleetLocator(_config(), 2.36, 1.75, TAGS)
    # Three rovers on their own circuits, 0.3 m/s at most, 30 frames a second.
    centres = {1: (0.6, 0.5), 2: (1.7, 0.5), 3: (0.7, 1.3)}
    worst_mm, worst_deg, frames = 0.0, 0.0, 150
    for k in range(frames):
        t = k / 30
        poses = {}
        for r, (cx, cy) in centres.items():
            a = 0.8 * t + 2.1 * r
            poses[r] = (cx + 0.25 * math.cos(a), cy + 0.25 * math.sin(a), math.degrees(-a) % 360)
        seen = locator.locate(renderer.render(_scene(poses), rng), t)
        assert seen.lost == [], (k, seen.reasons)
        assert seen.target is not None and math.hypot(seen.target.x_m - 2.1, seen.target.y_m - 1.5) < 0.005
        for r, truth in poses.items():
            got = seen.rovers[r]
            # Each fix is its own rover's: the nearest true pose to it is that rover's.
            nearest = min(poses, key=lambda q: math.hypot(poses[q][0] - got.x_m, poses[q][1] - got.y_m))
            assert nearest == r
            worst_mm = max(worst_mm, 1000 * math.hypot(got.x_m - truth[0], got.y_m - truth[1]))
            worst_deg = max(worst_deg, _angle_error(got.heading_deg, truth[2]))
    assert worst_mm < 4.0 and worst_deg < 2.0, (worst_mm, worst_deg)


def test_rovers_side_by_side_are_drawn_as_the_plain_drawing_draws_them_and_all_found():
    renderer = Renderer(RoverLook(), Camera(noise_sigma=0.0), seed=3)
    # Bodies 0.16 m apart centre to centre (0.15 m wide): their windows overlap.
    poses = {1: (1.0, 0.5, 0.0), 2: (1.16, 0.5, 0.0), 3: (1.32, 0.52, 10.0)}
    scene = _scene(poses)
    frame = renderer.render(scene, np.random.default_rng(0))
    assert np.array_equal(frame, renderer.reference_frame(scene))
    seen = FleetLocator(_config(), 2.36, 1.75, TAGS).locate(frame, 0.0)
    assert seen.lost == []
    for r, (x, y, _h) in poses.items():
        assert math.hypot(seen.rovers[r].x_m - x, seen.rovers[r].y_m - y) < 0.004


def test_a_rover_not_seen_is_named_with_why_and_the_others_are_still_found():
    renderer = Renderer(RoverLook(), Camera(noise_sigma=2.0), seed=4)
    rng = np.random.default_rng(1)
    locator = FleetLocator(_config(), 2.36, 1.75, TAGS)
    poses = {1: (0.5, 0.5, 30.0), 2: (1.5, 0.5, 200.0), 3: (0.8, 1.2, 90.0)}
    covered = dataclasses.replace(_scene(poses), fleet=((*poses[2], -1), (*poses[3], 4)))  # rover 2's tag covered
    seen = locator.locate(renderer.render(covered, rng), 0.0)
    assert seen.lost == [2]
    assert seen.reasons == {2: "rover 2 tag (id 3) not found"}
    assert seen.rovers[1] is not None and seen.rovers[3] is not None
    # Rover 3 seen 0.6 m away a tenth of a second later: refused as a jump, for rover 3 alone.
    moved = {**poses, 3: (1.4, 1.2, 90.0)}
    seen = locator.locate(renderer.render(_scene(moved), rng), 0.1)
    assert seen.lost == [3]
    assert seen.reasons[3].startswith("rover 3: jump of 0.60 m in 0.10 s")
    assert seen.rovers[2] is not None  # rover 2's first fix: nothing to jump from
    locator.reset(3)
    assert locator.locate(renderer.render(_scene(moved), rng), 0.2).lost == []


def test_a_fleet_needs_tags_of_its_own():
    with pytest.raises(ValueError, match="two rovers with one tag id"):
        FleetLocator(_config(), 2.36, 1.75, {1: 1, 2: 1})
    with pytest.raises(ValueError, match="the target's"):
        FleetLocator(_config(), 2.36, 1.75, {1: 1, 2: 2})
    with pytest.raises(ValueError, match="a fleet of no rovers"):
        FleetLocator(_config(), 2.36, 1.75, {})
    for bad in (-1, 50, 3.0, True):
        with pytest.raises(ValueError, match=r"tag id .* is not one of DICT_4X4_50's \(0 to 49\)"):
            FleetLocator(_config(), 2.36, 1.75, {1: 1, 2: bad})
    with pytest.raises(ValueError, match="told apart by ArUco tags"):
        FleetLocator(VisionConfig(), 2.36, 1.75, {1: 1})
    with pytest.raises(ValueError, match="marker_kind 'aruco'"):
        Renderer().render(
            dataclasses.replace(ARENA, marker_kind="colour", fleet=((1.0, 1.0, 0.0, 3),)), np.random.default_rng(0)
        )
