"""The camera process (rovernav.sim.camera_process) changes where frames are drawn and located,
and nothing else: a mission run with it is the mission run without it, sample for sample, event
for event, message for message in its log."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mcap.reader import make_reader

from rovernav.evaluation.report import build_report
from rovernav.runlog.images import encode_jpeg
from rovernav.scenario import load_scenario
from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.sim.camera_process import CameraProcess, CameraProcessError
from rovernav.sim.runner import Faults, SimOptions, Simulation
from rovernav.vision import Locator, VisionConfig


def _messages(path) -> list[tuple[str, int, bytes]]:
    """The log's messages in the order written: (topic, log time, data)."""
    with open(path, "rb") as f:
        return [(c.topic, m.log_time, m.data) for _s, c, m in make_reader(f).iter_messages(log_time_order=False)]


def _run(tmp_path, monkeypatch, name: str, camera_process: bool, **kw):
    log = tmp_path / f"{name}-{camera_process}.mcap"
    # The log's epoch (wall clock); the host's signing clock is simulated time already.
    monkeypatch.setattr("rovernav.runlog.writer.time.time_ns", lambda: 1_795_000_000_000_000_000)
    sim = Simulation(load_scenario(name), SimOptions(camera_process=camera_process, log=log, **kw))
    assert (sim._camera_proc is not None) == camera_process
    sim.run()
    sim.close_log()
    return sim, build_report(sim, 1.0), log


@pytest.mark.mission
@pytest.mark.parametrize(
    ("name", "kw"),
    [
        ("seed-fig4-8-unknown-obstacle", {"seed": 3}),
        # frames with no markers and none at all, and a host that starts again
        (
            "seed-large-obstacles",
            {
                "seed": 5,
                "max_time_s": 40.0,
                "faults": Faults(camera_outages=[(6.0, 2.0)], camera_outage_kind="no_markers", host_restarts=[12.0]),
            },
        ),
    ],
)
def test_a_mission_with_the_camera_process_is_the_mission_without_it(tmp_path, monkeypatch, name, kw):
    inline, inline_report, inline_log = _run(tmp_path, monkeypatch, name, False, **kw)
    beside, beside_report, beside_log = _run(tmp_path, monkeypatch, name, True, **kw)
    assert inline.frames_rendered > 300
    assert beside.frames_rendered == inline.frames_rendered
    assert beside.samples == inline.samples
    assert beside.events == inline.events
    assert beside_report == inline_report
    a, b = _messages(inline_log), _messages(beside_log)
    assert len(a) == len(b)
    images = [m for m in a if m[0] == "/camera/image"]
    assert len(images) > 10  # the log kept frames, encoded in the camera process in the second run
    differ = sorted({x[0] for x, y in zip(a, b) if x != y})
    assert differ == [], differ


def test_the_process_draws_and_locates_the_frames_the_loop_would():
    look, camera = RoverLook(), Camera(lighting=Lighting.random(np.random.default_rng(4)), noise_sigma=3.0)
    scene = Scene(
        arena_w_m=2.36,
        arena_h_m=1.75,
        obstacles=((1.2, 0.9, 0.2, 0.3),),
        walls=(),
        posts=(),
        target=(2.0, 1.4),
        marker_kind="colour",
        decoys=(),
    )
    proc = CameraProcess((look, camera, 77), (VisionConfig(), 2.36, 1.75))
    try:
        here_r, here_l = Renderer(look, camera, 77), Locator(VisionConfig(), 2.36, 1.75)
        rng_here, rng_there = np.random.default_rng(9), np.random.default_rng(9)
        for i in range(40):
            pose = (0.3 + 0.03 * i, 0.4 + 0.02 * i, 7.0 * i)
            if i == 20:
                pose = (-1.0, -1.0, 0.0)  # out of sight: a frame with no rover
            s = dataclasses.replace(scene, rover=pose)
            want_frame = here_r.render(s, rng_here)
            proc.submit(i / 30, scene, s.rover, s.hidden, here_r.noise_offsets(rng_there), keep_image=i % 7 == 0)
            det, jpeg = proc.take()
            assert det == here_l.locate(want_frame, i / 30)
            assert (jpeg is not None) == (i % 7 == 0)
            if jpeg is not None:
                assert jpeg == encode_jpeg(want_frame)
        with pytest.raises(CameraProcessError, match="no frame is waiting"):
            proc.take()
    finally:
        proc.close()


def test_a_camera_process_that_fails_says_why():
    proc = CameraProcess((RoverLook(), Camera(noise_sigma=3.0), 1), (VisionConfig(), 2.36, 1.75))
    try:
        bad = Scene(arena_w_m=2.36, arena_h_m=1.75, obstacles=(), walls=(), posts=(), target=None, marker_kind="paint")
        proc.submit(0.0, bad, (1.0, 1.0, 0.0), frozenset(), (0, 0), keep_image=False)
        with pytest.raises(CameraProcessError, match="marker_kind 'paint'"):
            proc.take()
    finally:
        proc.close()


@pytest.mark.mission
def test_one_camera_process_serves_simulations_one_after_another(tmp_path, monkeypatch):
    # The second simulation is set up while the first one's last frames are still in flight
    # (a mission ends with frames not yet located): the process forgets them and starts afresh.
    from rovernav.sim import camera_process

    kw = {"seed": 2, "max_time_s": 12.0}  # cut short: frames in flight at the end
    first, first_report, _ = _run(tmp_path, monkeypatch, "seed-small-obstacles", True, **kw)
    pid = camera_process._shared._proc.pid
    second, second_report, _ = _run(tmp_path, monkeypatch, "seed-large-obstacles", True, **kw)
    assert camera_process._shared._proc.pid == pid and not camera_process._shared.in_use
    inline, inline_report, _ = _run(tmp_path, monkeypatch, "seed-large-obstacles", False, **kw)
    assert second.samples == inline.samples and second_report == inline_report
    assert first_report["mission_time_s"] == 12.0


def test_a_camera_process_killed_mid_run_ends_the_command_as_an_internal_error(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import threading
    import time

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rovernav.cli",
            "sim",
            "out-and-back",
            "--no-video",
            "--quiet",
            "--no-log",
            "--out",
            str(tmp_path / "out"),
            "--camera-process",
            "on",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )

    def kill_the_camera() -> None:
        for _ in range(200):
            time.sleep(0.05)
            found = subprocess.run(
                ["pgrep", "-P", str(proc.pid), "-f", "rovernav.sim.camera_process"], capture_output=True, text=True
            ).stdout.split()
            if found:
                time.sleep(0.5)
                os.kill(int(found[0]), signal.SIGKILL)
                return

    threading.Thread(target=kill_the_camera, daemon=True).start()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 3
    assert (
        err.strip()
        .splitlines()[-1]
        .startswith("rovernav sim: internal error: CameraProcessError: the camera process stopped")
    )


def _small_camera():
    return (RoverLook(), Camera(noise_sigma=3.0), 5), (VisionConfig(), 2.36, 1.75)


def test_a_camera_process_that_dies_or_stops_answering_is_a_camera_process_error(monkeypatch):
    import os
    import signal

    from rovernav.sim import camera_process

    scene = Scene(arena_w_m=2.36, arena_h_m=1.75, target=(2.0, 1.4))
    proc = CameraProcess(*_small_camera())
    try:
        proc.submit(0.0, scene, (0.5, 0.5, 0.0), frozenset(), (1, 2), keep_image=False)
        proc.take()
        os.kill(proc._proc.pid, signal.SIGSTOP)  # alive, but answers nothing
        monkeypatch.setattr(camera_process, "ANSWER_TIMEOUT_S", 0.5)
        proc.submit(0.1, scene, (0.5, 0.5, 0.0), frozenset(), (1, 2), keep_image=False)
        with pytest.raises(CameraProcessError, match="did not answer in 0.5 s"):
            proc.take()
        os.kill(proc._proc.pid, signal.SIGKILL)
        proc._proc.wait()
        with pytest.raises(CameraProcessError, match=r"stopped \(exit code -9\)"):  # a send, not a BrokenPipeError
            for _ in range(50):  # the socket's buffer takes a few sends before it fails
                proc.submit(0.2, scene, (0.5, 0.5, 0.0), frozenset(), (1, 2), keep_image=False)
    finally:
        proc.close()


@pytest.mark.mission
def test_two_simulations_made_before_either_runs_get_a_camera_process_each(tmp_path, monkeypatch):
    from rovernav.sim import camera_process

    kw = {"seed": 4, "max_time_s": 8.0}
    a = Simulation(load_scenario("seed-small-obstacles"), SimOptions(camera_process=True, **kw))
    b = Simulation(load_scenario("seed-large-obstacles"), SimOptions(camera_process=True, **kw))
    assert a._camera_proc is not b._camera_proc and a._camera_proc is camera_process._shared
    private = b._camera_proc
    b.run()
    a.run()
    assert private._conn.closed  # b's own process: closed when b was done
    assert not camera_process._shared.in_use
    for sim, name in ((a, "seed-small-obstacles"), (b, "seed-large-obstacles")):
        inline = Simulation(load_scenario(name), SimOptions(camera_process=False, **kw))
        inline.run()
        assert sim.samples == inline.samples
