"""The overhead-frame renderer: what it draws, where, in which colours, how exactly and how fast."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from rovernav.angles import wrap_deg
from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene, render_frame
from rovernav.vision.calibration import Calibration
from rovernav.vision.config import VisionConfig

W, H = 2.36, 1.75
HSV = VisionConfig().hsv
RANGES = {name: getattr(HSV, name) for name in ("target", "rover_front", "rover_back")}


def _in_range(hsv_pixels: np.ndarray, rng_pair) -> np.ndarray:
    lo, hi = (np.array(b) for b in rng_pair)
    return np.all((hsv_pixels >= lo) & (hsv_pixels <= hi), axis=-1)


def test_a_frame_is_640_by_480_bgr_and_the_same_rng_gives_the_same_frame():
    scene = Scene(rover=(1.0, 0.8, 30.0), target=(2.0, 1.4), obstacles=((1.3, 0.9, 0.2, 0.85),))
    a = render_frame(scene, np.random.default_rng(4))
    b = render_frame(scene, np.random.default_rng(4))
    c = render_frame(scene, np.random.default_rng(5))
    assert a.shape == (480, 640, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)  # new noise
    assert np.abs(a.astype(int) - c.astype(int)).mean() < 6  # ... but only noise


@pytest.mark.parametrize(
    "lighting",
    [
        Lighting.uniform(),
        Lighting(level=1.05, gradient=0.25, vignette=0.35),
        Lighting(level=0.9, gradient=0.25, gradient_angle_deg=200, vignette=0.35),
    ],
)
def test_only_the_markers_fall_in_the_markers_hsv_ranges(lighting):
    """Floor, grout, obstacles, rover body and what lies beyond the arena are in no marker's range,
    under bright and dim uneven light; each marker is in its own (apart from its edge pixels)."""
    look = RoverLook()
    cam = Camera(lighting=lighting, noise_sigma=0.0)
    scene = Scene(rover=(0.6, 0.5, 20.0), target=(2.0, 1.4), obstacles=((1.3, 0.9, 0.3, 0.6),))
    frame = Renderer(look, cam).render(scene, np.random.default_rng(0))
    hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
    cal = cam.mapping(W, H)
    masks = {name: _in_range(hsv, r) for name, r in RANGES.items()}
    # Far from every marker, nothing is in any range.
    far = np.ones(frame.shape[:2], bool)
    for x, y, radius in ((0.6, 0.5, 0.16), (2.0, 1.4, 0.06)):
        u, v = cal.to_pixels((x, y))
        r_px = radius * 640 / W
        vv, uu = np.mgrid[0:480, 0:640]
        far &= (uu - u) ** 2 + (vv - v) ** 2 > r_px**2
    for name, m in masks.items():
        assert not (m & far).any(), f"{name} range matches {int((m & far).sum())} background pixels"
    # Each marker's centre pixel is in its own range.
    fwd = np.array([math.sin(math.radians(20.0)), math.cos(math.radians(20.0))])
    back = np.array([0.6, 0.5]) - look.centre_fraction * look.marker_distance_m * fwd
    front = back + look.marker_distance_m * fwd
    for name, p in (("rover_back", back), ("rover_front", front), ("target", (2.0, 1.4))):
        u, v = np.rint(cal.to_pixels(p)).astype(int)
        assert masks[name][v, u], f"{name} at {p}: HSV {hsv[v, u]}"


def test_a_marker_moved_by_a_tenth_of_a_pixel_moves_its_rendered_centroid_by_a_tenth():
    """Sub-pixel drawing: the intensity centroid of the (noise-free) target square follows its position."""
    cam = Camera(lighting=Lighting.uniform(), noise_sigma=0.0)
    r = Renderer(RoverLook(), cam)
    empty = r.render(Scene(), np.random.default_rng(0)).astype(np.float64)
    px_per_m = 640 / W
    for k in range(11):
        x = 1.0 + k * 0.1 / px_per_m  # steps of 0.1 px
        frame = r.render(Scene(target=(x, 0.9)), np.random.default_rng(0)).astype(np.float64)
        diff = np.abs(frame - empty).sum(axis=2)
        vv, uu = np.mgrid[0:480, 0:640]
        u = (diff * uu).sum() / diff.sum()
        expected_u = Calibration.straight_down(640, 480, W, H).to_pixels((x, 0.9))[0]
        assert abs(u - expected_u) < 0.02, (k, u, expected_u)


def test_an_oblique_camera_puts_the_arena_corners_at_the_calibrated_pixels():
    corners = [(60.0, 450.0), (600.0, 440.0), (520.0, 80.0), (130.0, 95.0)]
    cal = Calibration.from_corners(corners, W, H)
    frame = Renderer(RoverLook(), Camera(calibration=cal, lighting=Lighting.uniform(), noise_sigma=0.0)).render(
        Scene(), np.random.default_rng(0)
    )
    outside = np.array(RoverLook().outside_bgr)
    for (u, v), (du, dv) in zip(corners, [(-1, 1), (1, 1), (1, -1), (-1, -1)]):
        # Just outside each corner: beyond the arena; just inside: floor.
        out_px = frame[int(round(v + 4 * dv)), int(round(u + 4 * du))]
        in_px = frame[int(round(v - 6 * dv)), int(round(u - 6 * du))]
        assert np.abs(out_px.astype(int) - outside).max() <= 1
        assert in_px.mean() > outside.mean() + 40


@pytest.mark.parametrize("heading", [0.0, 90.0, 200.0])
def test_an_aruco_rover_is_a_readable_tag_whose_top_edge_faces_forward(heading):
    look = RoverLook()
    r = Renderer(look, Camera(lighting=Lighting.uniform(), noise_sigma=2.0))
    frame = r.render(Scene(rover=(1.0, 0.8, heading), target=(2.0, 1.4), marker_kind="aruco"), np.random.default_rng(1))
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50))
    corners, ids, _ = detector.detectMarkers(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    assert ids is not None and sorted(ids.ravel().tolist()) == [look.rover_tag_id, look.target_tag_id]
    c = corners[list(ids.ravel()).index(look.rover_tag_id)].reshape(4, 2)
    up = (c[0] + c[1]) / 2 - (c[2] + c[3]) / 2  # image pixels, v down
    seen = math.degrees(math.atan2(up[0], -up[1]))
    assert abs(wrap_deg(seen - heading)) < 3


def test_hidden_markers_and_decoys_are_drawn_as_asked():
    cam = Camera(lighting=Lighting.uniform(), noise_sigma=0.0)
    r = Renderer(RoverLook(), cam)
    hsv = cv2.cvtColor(
        r.render(
            Scene(
                rover=(1.0, 0.8, 0.0), hidden=frozenset({"front"}), decoys=(("back", 2.0, 0.3), ("target", 0.4, 1.5))
            ),
            np.random.default_rng(0),
        ),
        cv2.COLOR_BGR2HSV,
    )
    count = lambda name: cv2.connectedComponents(_in_range(hsv, RANGES[name]).astype(np.uint8))[0] - 1  # noqa: E731
    assert count("rover_front") == 0
    assert count("rover_back") == 2
    assert count("target") == 1
    with pytest.raises(ValueError, match="decoy kind"):
        r.render(Scene(decoys=(("purple", 1.0, 1.0),)), np.random.default_rng(0))


OBSTACLES = ((0.8, 1.2, 0.3, 0.15), (1.6, 0.45, 0.25, 0.25), (1.1, 0.7, 0.18, 0.18), (1.65, 1.15, 0.15, 0.15))
OBLIQUE = Calibration.from_corners([(60.0, 450.0), (600.0, 440.0), (520.0, 80.0), (130.0, 95.0)], W, H)


@pytest.mark.parametrize("markers", ["colour", "aruco"])
@pytest.mark.parametrize("calibration", [None, OBLIQUE], ids=["straight-down", "oblique"])
def test_a_cached_frame_is_the_whole_scene_drawn_plainly_pixel_for_pixel(markers, calibration):
    """render() keeps the lit arena and draws only a window round the rover; without noise its
    frame must be what reference_frame() paints on one full-frame image: the rover anywhere
    (crossing the frame's edge, off it, over the target, hidden markers), after the static scene
    changed and changed back."""
    cam = Camera(calibration=calibration, lighting=Lighting(level=1.0, gradient=0.25, vignette=0.35), noise_sigma=0.0)
    r = Renderer(RoverLook(), cam, seed=7)
    rng = np.random.default_rng(11)
    decoys = (("back", 0.3, 1.5), (7, 2.1, 0.3))
    arenas = [
        Scene(obstacles=OBSTACLES, target=(2.0, 1.4), marker_kind=markers, decoys=decoys),
        Scene(obstacles=OBSTACLES[:2], target=(0.5, 1.5), marker_kind=markers),
    ]
    poses = [
        (1.0, 0.8, 30.0),
        (2.0, 1.4, -75.0),
        (0.02, 0.9, 45.0),
        (2.33, 1.73, 200.0),
        (-0.5, 0.9, 0.0),
        (1.18, 0.02, 135.0),
    ] + [
        (float(rng.uniform(-0.05, W + 0.05)), float(rng.uniform(-0.05, H + 0.05)), float(rng.uniform(-180, 180)))
        for _ in range(6)
    ]
    checked = 0
    for k, pose in enumerate(poses):
        base = arenas[(k // 3) % 2]
        hidden = frozenset({"tag"} if markers == "aruco" else {"front"}) if k == 4 else frozenset()
        for scene in (dataclasses.replace(base, rover=pose, hidden=hidden), base):
            got = r.render(scene, rng)
            want = r.reference_frame(scene)
            diff = np.argwhere(got != want)
            assert diff.size == 0, f"rover {pose}: {len(diff)} values differ, first at {diff[0].tolist()}"
            checked += 1
    assert checked == 2 * len(poses)


def _noise_of(r: Renderer, scene: Scene, frames: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The noise of `frames` frames (frame minus the noiseless reference, int16) and where it can be
    seen unclipped (the noiseless value well inside 0-255)."""
    rng = np.random.default_rng(seed)
    clean = r.reference_frame(scene).astype(np.int16)
    noise = np.stack([r.render(scene, rng).astype(np.int16) - clean for _ in range(frames)])
    return noise, (clean > 20) & (clean < 235)


def _box_round(mask: np.ndarray, grow: int) -> tuple[slice, slice]:
    vv, uu = np.nonzero(mask)
    return slice(max(vv.min() - grow, 0), vv.max() + grow + 1), slice(max(uu.min() - grow, 0), uu.max() + grow + 1)


def test_the_noise_is_gaussian_everywhere_and_fresh_each_frame_where_the_locator_measures():
    """The floor's noise may come from a few noisy copies of the arena kept from frame to frame; the
    rover, the target and 6 px round them (where the locator weighs pixels for its centroids) get a
    new draw every frame. Everywhere the noise is the camera's: mean 0, standard deviation sigma
    (rounded: sqrt(sigma^2 + 1/12))."""
    sigma = 3.0
    cam = Camera(lighting=Lighting(level=1.0, gradient=0.2, vignette=0.3), noise_sigma=sigma)
    r = Renderer(RoverLook(), cam, seed=3)
    base = Scene(obstacles=OBSTACLES, target=(2.0, 1.4))
    scene = dataclasses.replace(base, rover=(0.9, 0.5, 40.0))
    noise, ok = _noise_of(r, scene, 24, seed=5)
    expected = math.sqrt(sigma**2 + 1 / 12)
    seen = noise[:, ok].astype(np.float64)
    assert abs(seen.mean()) < 0.02
    assert abs(seen.std() - expected) < 0.03 * expected
    # Where the locator measures: the rover and the target, grown by 6 px.
    rover_px = (r.reference_frame(scene) != r.reference_frame(base)).any(axis=2)
    target_px = (r.reference_frame(base) != r.reference_frame(dataclasses.replace(base, target=None))).any(axis=2)
    windows = {"rover": _box_round(rover_px, 6), "target": _box_round(target_px, 6)}
    # Frames whose floor noise is the same (one kept copy) must still differ there.
    floor = noise[:, 400:460, 20:80].reshape(len(noise), -1)
    pairs = [(i, j) for i in range(len(noise)) for j in range(i + 1, len(noise)) if np.array_equal(floor[i], floor[j])]
    patterns = len({floor[i].tobytes() for i in range(len(noise))})
    assert pairs and 4 <= patterns < len(noise), (len(pairs), patterns)
    for name, (vs, us) in windows.items():
        win = noise[:, vs, us].reshape(len(noise), -1).astype(np.float64)
        assert abs(win.std() - expected) < 0.06 * expected, name
        for i, j in pairs:
            c = np.corrcoef(win[i], win[j])[0, 1]
            assert abs(c) < 0.1, f"{name}: frames {i} and {j} share their noise there (correlation {c:.2f})"
