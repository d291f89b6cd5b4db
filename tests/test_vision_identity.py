"""The colour-marker finder, made faster, against the previous implementation kept as the reference
(rovernav/vision/colour_markers_reference.py): the same searches and the same fixes, bit for bit
(compared by repr, which tells every float apart, -0.0 from 0.0 too), on tracking sequences and
cold frames with noise and uneven light, markers lost, doubled, partly out of the tracking window,
at or over the frame's edge, on the target, and under configurations and frame sizes other than
the defaults."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.vision import Calibration, Locator, VisionConfig
from rovernav.vision.colour_markers import _ONES_1X3, _THREE, ColourMarkers
from rovernav.vision.colour_markers_reference import ReferenceColourMarkers, reference_locator

W, H = 2.36, 1.75
NAMES = ColourMarkers.NAMES
PIXEL = {"target": "target", "rover_front": "front", "rover_back": "back"}
OBLIQUE = [[70.0, 440.0], [590.0, 455.0], [540.0, 60.0], [120.0, 40.0]]  # a tilted, turned camera


def _scenes(rng: np.random.Generator, n: int, cold: bool = False):
    """n (scene, jumped) of a rover mostly wandering slowly (tracking), with now and then a fast step
    (a marker partly out of its window), a jump anywhere, a stretch near or over the frame's edge,
    a marker hidden for a few frames, a decoy, the target under the rover or absent."""
    x, y, h = rng.uniform(0.3, W - 0.3), rng.uniform(0.3, H - 0.3), rng.uniform(0.0, 360.0)
    hidden: frozenset[str] = frozenset()
    hidden_for = 0
    for _ in range(n):
        e = rng.random()
        jumped = cold or e < 0.03
        if cold or e < 0.015:  # a jump anywhere: the windows find nothing, the whole frame is searched
            x, y, h = rng.uniform(0.0, W), rng.uniform(0.0, H), rng.uniform(0.0, 360.0)
        elif e < 0.03:  # to an edge or a corner, markers partly outside the frame
            x = float(rng.choice([rng.uniform(-0.01, 0.06), rng.uniform(W - 0.06, W + 0.01), x]))
            y = float(rng.choice([rng.uniform(-0.01, 0.06), rng.uniform(H - 0.06, H + 0.01), y]))
        elif e < 0.12:  # a fast step: 5 to 25 px, the marker partly out of its window
            a = rng.uniform(0.0, 2 * math.pi)
            d = rng.uniform(0.02, 0.09)
            x, y, h = x + d * math.cos(a), y + d * math.sin(a), h + rng.normal(0.0, 20.0)
        else:  # tracking: a few millimetres a frame, back towards the middle from the edges
            if not (0.15 < x < W - 0.15 and 0.15 < y < H - 0.15):
                h = math.degrees(math.atan2(W / 2 - x, H / 2 - y))
            h += float(rng.normal(0.0, 3.0))
            x += 0.004 * math.sin(math.radians(h))
            y += 0.004 * math.cos(math.radians(h))
        x, y = min(max(x, -0.01), W + 0.01), min(max(y, -0.01), H + 0.01)
        if hidden_for:
            hidden_for -= 1
        else:
            hidden = frozenset()
            if rng.random() < 0.05:
                hidden, hidden_for = frozenset(rng.choice(["front", "back"], int(rng.integers(1, 3)), replace=False)), 3
        t = rng.random()
        target = (
            (2.0, 1.4) if t < 0.8 else None if t < 0.9 else (x + rng.uniform(-0.08, 0.08), y + rng.uniform(-0.08, 0.08))
        )
        decoys = ()
        if rng.random() < 0.05:
            decoys = (
                (str(rng.choice(["front", "back", "target"])), rng.uniform(0.1, W - 0.1), rng.uniform(0.1, H - 0.1)),
            )
        scene = Scene(rover=(x, y, h), target=target, obstacles=((1.2, 0.9, 0.2, 0.2),), hidden=hidden, decoys=decoys)
        yield scene, jumped


def _renderer(cfg: VisionConfig, rng: np.random.Generator, seed: int, width_px=640, height_px=480) -> Renderer:
    light = Lighting.random(rng) if seed % 3 else Lighting(level=0.6, gradient=0.35, vignette=0.4)  # dim, uneven
    cal = None if cfg.calibration is None else Calibration.from_config(cfg.calibration)
    cam = Camera(width_px, height_px, cal, light, noise_sigma=float(rng.uniform(2.0, 8.0)))
    return Renderer(RoverLook.for_vision(cfg), cam, seed=seed)


def _check_sequence(cfg: VisionConfig, seed: int, n: int, width_px=640, height_px=480, cold=False) -> dict:
    """Both locators over one sequence, and both finders with hints put off the markers on purpose;
    returns counts of what the sequence exercised."""
    rng = np.random.default_rng(seed)
    renderer = _renderer(cfg, rng, seed, width_px, height_px)
    new, ref = Locator(cfg, W, H), reference_locator(cfg, W, H)
    fast, slow = ColourMarkers(cfg), ReferenceColourMarkers(cfg)
    seen = {"fixes": 0, "no fix": 0, "window found": 0, "window gave up": 0}
    for i, (scene, jumped) in enumerate(_scenes(rng, n, cold)):
        frame = renderer.render(scene, rng)
        if cold or (jumped and i % 4):  # every frame alone, or the rover moved by hand
            new.reset()
            ref.reset()
        hints = dict(ref._colour_hints)
        a, b = new.locate(frame, i / 30), ref.locate(frame, i / 30)
        assert repr(a) == repr(b), (seed, i, scene)
        seen["fixes" if b.rover is not None else "no fix"] += 1
        # The same frame searched from hints moved off the markers: partly out of their windows,
        # clipped by the frame's edges, or nowhere near (a window holding nothing).
        moved = {}
        for name in NAMES:
            u, v = hints.get(name, b.pixels.get(PIXEL[name], (rng.uniform(0, width_px), rng.uniform(0, height_px))))
            k = rng.integers(4)
            if k == 1:
                u, v = u + rng.uniform(-70, 70), v + rng.uniform(-70, 70)
            elif k == 2:
                u, v = (
                    rng.choice([rng.uniform(-5, 40), u, rng.uniform(width_px - 40, width_px + 5)]),
                    rng.choice([rng.uniform(-5, 40), v, rng.uniform(height_px - 40, height_px + 5)]),
                )
            elif k == 3:
                u, v = rng.uniform(0, width_px), rng.uniform(0, height_px)
            moved[name] = (float(u), float(v))
        for h in (hints, moved):
            fa, fb = fast.find(frame, h), slow.find(frame, h)
            assert repr(fa) == repr(fb), (seed, i, h, scene)
            for name in h:
                win_a = fast._find_in_window(name, frame, h[name])
                win_b = slow._find_in_window(name, frame, h[name])
                assert repr(win_a) == repr(win_b), (seed, i, name, h[name])
                seen["window found" if win_b is not None else "window gave up"] += 1
    return seen


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_tracking_sequences_give_the_references_fixes_bit_for_bit(seed):
    seen = _check_sequence(VisionConfig(), seed, 150)
    assert seen["fixes"] > 30 and seen["no fix"] > 10 and seen["window found"] > 150 and seen["window gave up"] > 100


def test_cold_frames_give_the_references_fixes_bit_for_bit():
    seen = _check_sequence(VisionConfig(), 11, 80, cold=True)
    assert seen["fixes"] > 30 and seen["no fix"] > 10


@pytest.mark.parametrize(
    "table, size",
    [
        ({"downscale": 1}, (640, 480)),
        ({"downscale": 3, "open_kernel_px": 5, "close_kernel_px": 3}, (640, 480)),
        ({"open_kernel_px": 4, "close_kernel_px": 2}, (640, 480)),
        ({"open_kernel_px": 1, "close_kernel_px": 1, "min_blob_area_px": 10}, (640, 480)),
        ({}, (641, 479)),  # odd sizes: windows clipped by the frame are odd too
        ({"downscale": 3}, (500, 373)),
        ({"calibration": {"corners_px": OBLIQUE, "width_m": W, "height_m": H}}, (640, 480)),  # no shortcut
    ],
)
def test_other_configurations_and_frame_sizes_give_the_references_fixes(table, size):
    _check_sequence(VisionConfig.from_dict(table), 21, 60, width_px=size[0], height_px=size[1])


def test_the_grey_level_is_numpys_mean_for_every_sum_of_three_channels():
    """The fast grey level (the channels' sum by cv2.transform, divided by float32(3)) against what
    the reference computed (numpy's mean over the channels: a float32 sum divided by intp(3) in
    float64, rounded to float32), for every sum a pixel's three channels can have."""
    s = np.arange(766)
    a = np.minimum(s, 255)
    b = np.minimum(s - a, 255)
    pixels = np.stack([a, b, s - a - b], axis=1).astype(np.uint8).reshape(1, -1, 3).astype(np.float32)
    want = pixels.mean(axis=2)
    got = cv2.transform(pixels, _ONES_1X3) / _THREE
    assert np.array_equal(got.view(np.uint32), want.view(np.uint32))


def test_the_hsv_conversion_is_the_same_whatever_a_pixels_place_in_its_row():
    """_refine converts a strip 32k pixels wide and cuts the window out of it, where the reference
    converted the window alone: OpenCV's SIMD code (whole blocks) and its scalar code (a row's last
    pixels) must give every BGR colour the same HSV, as they do on this build (all 2^24 colours)."""
    c = np.arange(2**24, dtype=np.uint32)
    bgr = np.stack([(c >> 16) & 255, (c >> 8) & 255, c & 255], axis=1).astype(np.uint8)
    simd = cv2.cvtColor(bgr.reshape(-1, 32, 3), cv2.COLOR_BGR2HSV).reshape(-1, 3)
    scalar = cv2.cvtColor(bgr.reshape(-1, 1, 3), cv2.COLOR_BGR2HSV).reshape(-1, 3)
    assert np.array_equal(simd, scalar)
    n = 2**24 // 26 * 26
    assert np.array_equal(cv2.cvtColor(bgr[:n].reshape(-1, 26, 3), cv2.COLOR_BGR2HSV).reshape(-1, 3), simd[:n])


def test_erosion_and_dilation_of_a_view_read_nothing_beyond_it():
    """_mask and _refine erode and dilate views (crops, cut strips): OpenCV must treat a view's edges
    as the image's edges, as it treats a whole array's."""
    full = np.full((12, 12), 255, np.uint8)
    full[:, 6] = 0
    full[8, :] = 0
    view = full[2:8, 0:6]  # all 255, next to zeros
    k = np.ones((3, 3), np.uint8)
    assert cv2.erode(view, k).min() == 255
    assert cv2.morphologyEx(view, cv2.MORPH_CLOSE, k).min() == 255
    inverse = 255 - full
    assert cv2.dilate(inverse[2:8, 0:6], k).max() == 0  # all 0, next to 255s


@pytest.mark.parametrize("size", [(640, 480), (641, 479), (320, 240), (1920, 1080)])
def test_one_point_to_the_arena_is_what_the_matrix_product_gives(size):
    """Calibration.to_arena's shortcut for one (u, v) tuple through a straight-down mapping, against
    Calibration._apply, bit for bit: over and beyond the frame, at its edges and at exact zeros."""
    cal = Calibration.straight_down(*size, W, H)
    assert cal._axis_scales is not None  # the shortcut is taken
    rng = np.random.default_rng(size[0])
    w, h = size
    us = np.concatenate([rng.uniform(-w, 2 * w, 20000), [0.0, -0.0, -0.5, w - 0.5, w, 1e-300, -1e-300]])
    vs = np.concatenate([rng.uniform(-h, 2 * h, 20000), [0.0, -0.0, -0.5, h - 0.5, h, -1e-300, 1e-300]])
    for u, v in zip(us.tolist(), vs.tolist()):
        got = cal.to_arena((u, v))
        want = Calibration._apply(cal.arena_from_pixel, (u, v))
        assert got.shape == want.shape == (2,) and got.tobytes() == want.tobytes(), (u, v)


def test_an_oblique_calibration_takes_no_shortcut():
    cal = Calibration.from_corners(OBLIQUE, W, H)
    assert cal._axis_scales is None
