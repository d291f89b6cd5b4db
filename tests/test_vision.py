"""Vision on rendered frames: accuracy under noise and uneven light, missing, doubled and
implausible markers, an oblique camera, ArUco, configuration errors, and `rovernav locate`."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import cv2
import numpy as np
import pytest

from rovernav.render import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.vision import Locator, VisionConfig
from rovernav.vision.calibration import Calibration

W, H = 2.36, 1.75


def _renderer(cfg: VisionConfig, seed: int = 0, camera: Camera | None = None, lighting=None) -> Renderer:
    cam = camera or Camera(lighting=lighting or Lighting(), noise_sigma=3.0)
    return Renderer(RoverLook.for_vision(cfg), cam, seed=seed)


def _heading_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("light_seed", [1, 2, 3])
def test_pose_within_5_mm_and_1_degree_under_noise_and_uneven_light(light_seed):
    cfg = VisionConfig()
    rng = np.random.default_rng(light_seed)
    r = _renderer(cfg, seed=light_seed, lighting=Lighting.random(rng))
    loc = Locator(cfg, W, H)
    worst_mm = worst_deg = 0.0
    for _ in range(40):
        x, y, h = rng.uniform(0.25, W - 0.25), rng.uniform(0.25, H - 0.25), rng.uniform(-180, 180)
        frame = r.render(Scene(rover=(x, y, h), target=(2.0, 1.4), obstacles=((1.2, 0.9, 0.2, 0.2),)), rng)
        loc.reset()
        det = loc.locate(frame)
        assert det.rover is not None, det.reason
        worst_mm = max(worst_mm, 1000 * math.hypot(det.rover[0] - x, det.rover[1] - y))
        worst_deg = max(worst_deg, _heading_error(det.rover[2], h))
        # The target is a smaller square, often in the darkest corner: a looser bound.
        assert det.target is not None and math.hypot(det.target[0] - 2.0, det.target[1] - 1.4) < 0.02
    assert worst_mm < 5.0
    assert worst_deg < 1.0


def test_a_still_scene_gives_a_steady_heading_not_the_seeds_2_5_degree_jumps():
    cfg = VisionConfig()
    r = _renderer(cfg)
    loc = Locator(cfg, W, H)
    rng = np.random.default_rng(7)
    headings = []
    for _ in range(30):  # the same scene, new sensor noise every frame
        det = loc.locate(r.render(Scene(rover=(1.03, 0.77, 33.3), target=(2.0, 1.4)), rng))
        headings.append(det.rover[2])
    assert max(headings) - min(headings) < 0.5


@pytest.mark.parametrize("hidden, words", [
    (frozenset({"front"}), "front marker (orange) not found"),
    (frozenset({"back"}), "back marker (green) not found"),
])
def test_a_missing_marker_gives_no_fix_and_says_which(hidden, words):
    cfg = VisionConfig()
    frame = _renderer(cfg).render(Scene(rover=(1.0, 0.8, 10.0), target=(2.0, 1.4), hidden=hidden),
                                  np.random.default_rng(1))
    det = Locator(cfg, W, H).locate(frame)
    assert det.rover is None
    assert words in det.reason


def test_a_doubled_marker_gives_no_fix():
    cfg = VisionConfig()
    frame = _renderer(cfg).render(Scene(rover=(1.0, 0.8, 10.0), target=(2.0, 1.4), decoys=(("back", 1.8, 0.4),)),
                                  np.random.default_rng(1))
    det = Locator(cfg, W, H).locate(frame)
    assert det.rover is None
    assert "two candidate" in det.reason and "green" in det.reason


def test_markers_implausibly_far_apart_give_no_fix():
    cfg = VisionConfig()
    look = RoverLook.for_vision(cfg, marker_distance_m=0.20)   # a rover built wrong
    r = Renderer(look, Camera(), seed=0)
    det = Locator(cfg, W, H).locate(r.render(Scene(rover=(1.0, 0.8, 60.0)), np.random.default_rng(2)))
    assert det.rover is None
    assert "apart, expected" in det.reason


def test_a_jump_the_rover_could_not_have_made_gives_no_fix():
    cfg = VisionConfig()
    r = _renderer(cfg)
    loc = Locator(cfg, W, H)
    rng = np.random.default_rng(3)
    assert loc.locate(r.render(Scene(rover=(0.5, 0.5, 0.0)), rng), t_s=0.0).rover is not None
    det = loc.locate(r.render(Scene(rover=(1.5, 1.2, 0.0)), rng), t_s=0.033)
    assert det.rover is None
    assert "jump of" in det.reason
    # Moving as a rover can, it is accepted.
    assert loc.locate(r.render(Scene(rover=(0.505, 0.5, 0.0)), rng), t_s=0.066).rover is not None


def test_an_oblique_camera_with_a_calibration_stays_within_tolerance():
    corners = [(70.0, 440.0), (590.0, 455.0), (540.0, 60.0), (120.0, 40.0)]   # a tilted, rotated view
    cal = Calibration.from_corners(corners, W, H)
    cfg = VisionConfig.from_dict({"calibration": {"corners_px": [list(c) for c in corners],
                                                  "width_m": W, "height_m": H}})
    r = _renderer(cfg, camera=Camera(calibration=cal, noise_sigma=3.0))
    loc = Locator(cfg, W, H)
    rng = np.random.default_rng(11)
    for _ in range(20):
        x, y, h = rng.uniform(0.3, W - 0.3), rng.uniform(0.3, H - 0.3), rng.uniform(-180, 180)
        loc.reset()
        det = loc.locate(r.render(Scene(rover=(x, y, h)), rng))
        assert det.rover is not None, det.reason
        assert 1000 * math.hypot(det.rover[0] - x, det.rover[1] - y) < 5.0
        assert _heading_error(det.rover[2], h) < 1.0


def test_aruco_markers_locate_the_rover_and_the_target():
    cfg = VisionConfig(markers="aruco")
    r = _renderer(cfg)
    loc = Locator(cfg, W, H)
    rng = np.random.default_rng(5)
    for x, y, h in ((0.6, 0.5, 0.0), (1.5, 1.1, 135.0), (1.0, 0.9, -70.0)):
        det = loc.locate(r.render(Scene(rover=(x, y, h), target=(2.0, 1.4), marker_kind="aruco"), rng))
        assert det.rover is not None, det.reason
        assert 1000 * math.hypot(det.rover[0] - x, det.rover[1] - y) < 5.0
        # A 10 cm tag is 27 pixels wide here: its heading is good to about 2 degrees, the colour
        # markers' (9 cm apart, centroids of whole squares) to well under 1.
        assert _heading_error(det.rover[2], h) < 2.5
        assert det.target is not None and math.hypot(det.target[0] - 2.0, det.target[1] - 1.4) < 0.01
    hidden = loc.locate(r.render(Scene(rover=(1.0, 0.9, 0.0), marker_kind="aruco", hidden=frozenset({"tag"})), rng))
    assert hidden.rover is None and "rover tag" in hidden.reason


@pytest.mark.parametrize("table, words", [
    ({"markers": "lasers"}, "vision.markers"),
    ({"hsv": {"target": [[40, 40, 50], [35, 255, 255]]}}, "vision.hsv.target"),
    ({"bogus": 1}, "bogus"),
    ({"marker_distance_m": -1}, "vision.marker_distance_m"),
])
def test_bad_vision_configuration_names_the_key(table, words):
    with pytest.raises(ValueError, match=words.replace(".", r"\.")):
        VisionConfig.from_dict(table)


def test_rovernav_locate_prints_json_and_exit_codes(tmp_path):
    cfg = VisionConfig()
    frame = _renderer(cfg).render(Scene(rover=(1.2, 0.6, 45.0), target=(2.0, 1.4)), np.random.default_rng(1))
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), frame)
    run = [sys.executable, "-m", "rovernav.cli", "locate"]
    out = subprocess.run(run + [str(image), "--json"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert abs(data["rover"]["x_m"] - 1.2) < 0.005 and abs(data["rover"]["heading_deg"] - 45.0) < 1.0
    assert abs(data["target"]["x_m"] - 2.0) < 0.005 and data["reason"] is None
    empty = tmp_path / "empty.png"
    cv2.imwrite(str(empty), _renderer(cfg).render(Scene(), np.random.default_rng(1)))
    out = subprocess.run(run + [str(empty), "--json"], capture_output=True, text=True)
    assert out.returncode == 1 and json.loads(out.stdout)["rover"] is None
    out = subprocess.run(run + [str(tmp_path / "missing.png")], capture_output=True, text=True)
    assert out.returncode == 2 and "cannot read image" in out.stderr
