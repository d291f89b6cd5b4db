"""The annotated video: H.264 through PyAV (libx264), its hidden partial file, and its size."""

from __future__ import annotations

import hashlib

import av
import cv2
import numpy as np
import pytest

from rovernav.evaluation.report import VideoWriter
from rovernav.scenario import load_scenario
from rovernav.sim.runner import SimOptions, Simulation


def _frames(n: int, seed: int = 0):
    """n 640x480 BGR frames like the camera's: a grey floor with sensor noise, a box moving across
    it, and a status line on a black bar."""
    rng = np.random.default_rng(seed)
    floor = np.full((480, 640, 3), 150, np.uint8)
    cv2.rectangle(floor, (400, 300), (470, 380), (110, 110, 110), -1)
    for i in range(n):
        img = cv2.add(floor, rng.integers(0, 7, floor.shape, dtype=np.uint8))
        cv2.rectangle(img, (40 + 4 * i, 200), (90 + 4 * i, 240), (30, 30, 30), -1)
        cv2.rectangle(img, (0, 0), (640, 22), (0, 0, 0), -1)
        cv2.putText(img, f"t {i / 30:6.1f} s", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        yield img


def _probe(path):
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        cc = s.codec_context
        decoded = [f.to_ndarray(format="bgr24") for f in c.decode(video=0)]
        return {
            "codec": cc.name,
            "pix_fmt": cc.pix_fmt,
            "size": (cc.width, cc.height),
            "rate": s.average_rate,
            "frames": len(decoded),
            "last": decoded[-1] if decoded else None,
        }


def _top_level_boxes(path) -> list[str]:
    """The MP4 file's top-level box types, in file order."""
    data = path.read_bytes()
    out, at = [], 0
    while at + 8 <= len(data):
        size, kind = int.from_bytes(data[at : at + 4], "big"), data[at + 4 : at + 8].decode("latin-1")
        if size == 1:
            size = int.from_bytes(data[at + 8 : at + 16], "big")
        out.append(kind)
        if size < 8:
            break
        at += size
    return out


def test_frames_written_come_back_as_h264_640x480_at_the_rate_given(tmp_path):
    path = tmp_path / "video.mp4"
    video = VideoWriter(path, 30.0)
    frames = list(_frames(45))
    for img in frames:
        video.write(img)
    assert video.frames == 45 and video.codec == "libx264"
    assert video.partial.exists() and not path.exists()  # written under the hidden name until closed
    video.close()
    assert path.exists() and not video.partial.exists()
    assert not list(tmp_path.glob(".*partial*"))
    got = _probe(path)
    assert got["codec"] == "h264" and got["pix_fmt"] == "yuv420p" and got["size"] == (640, 480)
    assert got["frames"] == 45 and got["rate"] == 30
    # the last frame is the last written (nothing lost in the encoder's queue), near enough
    assert cv2.PSNR(got["last"], frames[-1]) > 30
    boxes = _top_level_boxes(path)  # +faststart: the index (moov) before the data (mdat), for browsers
    assert boxes.index("moov") < boxes.index("mdat"), boxes


def test_a_fractional_camera_rate_is_kept(tmp_path):
    video = VideoWriter(tmp_path / "v.mp4", 12.5)
    for img in _frames(10):
        video.write(img)
    video.close()
    got = _probe(tmp_path / "v.mp4")
    assert got["frames"] == 10 and got["rate"] == pytest.approx(12.5)


def test_close_without_keep_leaves_no_file(tmp_path):
    path = tmp_path / "video.mp4"
    video = VideoWriter(path, 30.0)
    for img in _frames(5):
        video.write(img)
    video.close(keep=False)
    assert list(tmp_path.iterdir()) == []
    video.close(keep=False)  # twice is harmless; so is closing a writer that never got a frame
    VideoWriter(tmp_path / "none.mp4", 30.0).close()
    assert list(tmp_path.iterdir()) == []


def test_no_h264_encoder_is_a_clear_error_and_leaves_no_file(tmp_path, monkeypatch):
    monkeypatch.setattr(VideoWriter, "ENCODERS", ("no_such_h264_encoder",))
    video = VideoWriter(tmp_path / "video.mp4", 30.0)
    with pytest.raises(RuntimeError, match="no H.264 encoder.*no_such_h264_encoder.*--no-video"):
        video.write(next(_frames(1)))
    assert list(tmp_path.iterdir()) == []


def test_a_short_mission_video_is_small_and_leaves_the_cameras_frames_alone(tmp_path):
    """Out-and-back's first 10 simulated seconds through the writer as `rovernav sim` uses it.
    The whole mission makes 2.9 MB (benchmarks/bench_video.py), the old OpenCV mp4v video 26 MB;
    a fall-back to anything ten times bigger fails here."""
    video = VideoWriter(tmp_path / "video.mp4", 30.0)
    changed = []

    def sink(t_s, frame, sim):
        before = hashlib.sha1(frame).digest()
        video(t_s, frame, sim)
        if hashlib.sha1(frame).digest() != before:
            changed.append(t_s)

    sim = Simulation(load_scenario("out-and-back"), SimOptions(seed=1, max_time_s=10.0), frame_sink=sink)
    sim.run()
    video.close()
    assert changed == []  # the annotations go on a copy: the host's frames are the camera's
    assert video.frames == sim.frames_rendered > 250
    got = _probe(video.path)
    assert got["codec"] == "h264" and got["size"] == (640, 480) and got["frames"] == video.frames
    seconds = video.frames / 30.0
    kbit_s = video.path.stat().st_size * 8 / seconds / 1000
    # 5 MB for the whole mission (about 200 s) is 200 kbit/s; libx264 makes these 10 s 145 kbit/s
    # (the first key frame weighs on so short a video), the old mp4v 1,080 kbit/s.
    assert kbit_s < 400, f"{kbit_s:.0f} kbit/s over {seconds:.1f} s"
