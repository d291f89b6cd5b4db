"""Hostile input to `rovernav run` and `rovernav demo`: a bad map, configuration, scenario,
camera or port is one line and exit 2 before any device is opened; Ctrl-C stops the rover,
leaves the map whole and exits 130; a missing AVR toolchain, make or simavr is one line; and the
host's exceptions are one small tree. (Split from test_hostile_link.py.)"""

from __future__ import annotations

import os
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from tests.hostile_maps import BAD_MAPS, grid, map_text, reading

from rovernav import cli, files
from rovernav.errors import MapFileError
from rovernav.link import messages_gen as mg
from rovernav.link.errors import LinkClosed, LinkError, PortSpecError
from rovernav.link.link import Link
from rovernav.link.transport import PipeTransport
from rovernav.mapping import SonarReading
from rovernav.mapping.learned_map import LearnedMap, read_map_file

# ------------------------------------------------------------------ cases 1 and 4: `rovernav run`


@pytest.fixture
def no_devices(monkeypatch):
    """`rovernav run` must refuse its input before it opens any device: opening one fails the test."""
    from rovernav import hardware

    opened: list[str] = []

    def camera(source):
        opened.append(f"camera {source}")
        raise AssertionError("the camera was opened before the input was checked")

    def serial(*args, **kw):
        opened.append(f"port {args}")
        raise AssertionError("the port was opened before the input was checked")

    monkeypatch.setattr(hardware, "open_camera", camera)
    monkeypatch.setattr(hardware, "SerialTransport", serial)
    return opened


def run_cli(argv, capsys) -> tuple[int, str]:
    try:
        rc = cli.main(argv)
    except SystemExit as exc:
        rc = exc.code
    return rc, capsys.readouterr().err.strip()


@pytest.mark.parametrize("content, words", [(c, w) for _, c, w in BAD_MAPS[:12]], ids=[i for i, _, _ in BAD_MAPS[:12]])
def test_run_with_a_bad_map_fails_in_one_line_before_any_device_is_opened(tmp_path, capsys, no_devices, content, words):
    bad = tmp_path / "bad.json"
    bad.write_bytes(content)
    rc, err = run_cli(["run", "--port", "/dev/null", "--map", str(bad)], capsys)
    assert rc == 2 and no_devices == []
    assert err.startswith("rovernav run: ") and words in err and str(bad) in err and len(err.splitlines()) == 1
    assert bad.read_bytes() == content  # the bad file is left as it was


@pytest.mark.parametrize(
    "make, words", [("folder", "is a folder"), ("nodir", "no folder"), ("device", "not a regular file")]
)
def test_run_with_a_map_path_it_cannot_use_fails_before_any_device_is_opened(tmp_path, capsys, no_devices, make, words):
    path = {"folder": tmp_path, "nodir": tmp_path / "no" / "map.json", "device": Path("/dev/zero")}[make]
    if make == "device" and not path.exists():
        pytest.skip("needs /dev/zero")
    rc, err = run_cli(["run", "--port", "/dev/null", "--map", str(path)], capsys)
    assert rc == 2 and no_devices == [] and words in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    "toml, words",
    [
        ("[arena]\nwidth_m = -1\n", "width_m"),
        ("[link]\nbaud = 12345\n", "baud"),
        ('[link]\nport = "loop://"\n', "[link] port"),
        ('[link]\nport = "/dev/ttyUSB0@1"\n', "[link] port"),
        ('[camera]\nsource = "no-such-video.mp4"\n', "no-such-video.mp4"),
        ('[mission]\nmap = "no/such/folder/map.json"\n', "no folder"),
        ("[[[", "TOML"),
    ],
)
def test_run_with_a_bad_configuration_fails_in_one_line_naming_it_before_any_device_is_opened(
    tmp_path, capsys, no_devices, toml, words
):
    cfg = tmp_path / "rover.toml"
    cfg.write_text(toml)
    rc, err = run_cli(
        ["run", "--port", "/dev/null", "--config", str(cfg)] if "port" not in toml else ["run", "--config", str(cfg)],
        capsys,
    )
    assert rc == 2 and no_devices == [], err
    assert words in err and len(err.splitlines()) == 1 and "Traceback" not in err
    if "baud" in words or "width_m" in words or "[link]" in words:
        assert str(cfg) in err


@pytest.mark.parametrize(
    "argv, words",
    [
        (["run", "--port", "/dev/null", "--scenario", "no-such-scenario.toml"], "no-such-scenario"),
        (["run", "--port", "/dev/null", "--camera", "99999999"], "camera index"),
        (["run", "--port", "/dev/null", "--camera", "missing.mp4"], "no such file"),
        (["run", "--port", "loop://x"], "not a serial port"),
        (["run", "--port", "/dev/ttyUSB0@fast"], "bad baud rate 'fast'"),
    ],
)
def test_run_with_a_bad_scenario_camera_or_port_fails_before_any_device_is_opened(
    capsys, no_devices, argv, words, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    rc, err = run_cli(argv, capsys)
    assert rc == 2 and no_devices == [], err
    assert words in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    "flag, make, words",
    [
        ("--config", "device", "not a regular file"),
        ("--scenario", "device", "not a regular file"),
        ("--scenario", "fifo", "not a regular file"),
        ("--scenario", "folder", "is a folder"),
        ("--config", "huge", "a configuration file is at most"),
    ],
)
def test_run_refuses_a_config_or_scenario_that_is_a_device_a_pipe_or_huge_without_reading_it(
    tmp_path, capsys, no_devices, flag, make, words
):
    if make == "device":
        if not os.path.exists("/dev/zero"):
            pytest.skip("needs /dev/zero")
        path = Path("/dev/zero")  # read whole, it would never end
    elif make == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("needs mkfifo")
        path = tmp_path / "pipe.toml"
        os.mkfifo(path)  # read, it would wait for a writer for ever
    elif make == "folder":
        path = tmp_path
    else:
        path = tmp_path / "huge.toml"
        with open(path, "wb") as f:
            f.truncate(1 << 30)
    rc, err = run_cli(["run", "--port", "/dev/null", flag, str(path)], capsys)
    assert rc == 2 and no_devices == [] and words in err and len(err.splitlines()) == 1, err


class FakeCamera:
    """Frames for ever; Ctrl-C (KeyboardInterrupt) at frame `interrupt_at`."""

    def __init__(self, interrupt_at: int) -> None:
        self.frames, self.interrupt_at, self.released = 0, interrupt_at, False

    def read(self):
        import numpy as np

        self.frames += 1
        if self.frames == self.interrupt_at:
            raise KeyboardInterrupt
        time.sleep(0.005)
        return True, np.zeros((48, 64, 3), np.uint8)

    def release(self) -> None:
        self.released = True


class FakeLocator:
    def __init__(self, *args) -> None:
        pass

    def locate(self, frame, t):
        from rovernav.vision.locator import RoverPose, TargetPosition

        return SimpleNamespace(rover=RoverPose(0.5, 0.5, 0.0), target=TargetPosition(1.8, 1.2), reason=None)


@pytest.fixture
def fake_rig(monkeypatch, tmp_path_factory):
    """`rovernav run` with a fake camera and locator, its port one end of a pipe (the rover's end
    returned), run from a folder of its own (where its run log goes)."""
    from rovernav import hardware, vision

    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))
    host_end, rover_end = PipeTransport.pair("radio")
    camera = FakeCamera(interrupt_at=25)
    monkeypatch.setattr(hardware, "open_camera", lambda source: camera)
    monkeypatch.setattr(hardware, "SerialTransport", lambda name, baud: host_end)
    monkeypatch.setattr(vision, "Locator", FakeLocator)
    yield camera, host_end, Link(rover_end)
    rover_end.close()


def test_ctrl_c_stops_the_rover_saves_the_map_whole_and_exits_130(tmp_path, capsys, fake_rig):
    camera, host_end, rover = fake_rig
    lm = LearnedMap(grid())
    lm.add(SonarReading(1.0, 0.9, 90.0, 0.0, 0.25, 0.4, 0.003))
    lm.save(tmp_path / "map.json")
    rc, err = run_cli(["run", "--port", "/dev/ttyFAKE", "--map", str(tmp_path / "map.json")], capsys)
    assert rc == 130 and "interrupted" in err
    assert camera.released and host_end.closed
    said = []
    with pytest.raises(LinkClosed):  # everything the host sent, then the end of the line
        while True:
            frame = rover.recv(timeout_s=0)
            if frame is not None:
                said.append(frame.message)
    assert mg.Stop(reason=mg.StopReason.OPERATOR) in said  # the rover was told to stop
    assert len(read_map_file(tmp_path / "map.json")) == 1  # the map is whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.json"]  # no temporary file left
    # ... and the run's log too, under its default name, whole and replayable.
    from rovernav.runlog.replay import read_log

    logs = sorted(Path.cwd().iterdir())
    assert len(logs) == 1 and logs[0].name.startswith("run-") and logs[0].suffix == ".mcap"
    assert read_log(logs[0]).summary["interrupted"] is True


def test_ctrl_c_while_the_map_is_being_saved_leaves_the_old_map_whole(tmp_path, capsys, fake_rig, monkeypatch):
    camera, host_end, rover = fake_rig
    old = map_text([reading()]) + "\n"
    (tmp_path / "map.json").write_text(old)

    def interrupted_replace(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(files.os, "replace", interrupted_replace)
    rc, err = run_cli(["run", "--port", "/dev/ttyFAKE", "--map", str(tmp_path / "map.json")], capsys)
    assert rc == 130
    assert (tmp_path / "map.json").read_text() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.json"]
    assert camera.released and host_end.closed


def test_a_new_map_file_is_written_at_the_end_of_an_interrupted_run(tmp_path, capsys, fake_rig):
    rc, _ = run_cli(["run", "--port", "/dev/ttyFAKE", "--map", str(tmp_path / "new.json")], capsys)
    assert rc == 130
    assert read_map_file(tmp_path / "new.json") == []


# ------------------------------------------------------------------ case 5: `rovernav demo`


def test_demo_without_the_avr_toolchain_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # no avr-gcc, no make, no simavr
    rc, err = run_cli(["demo", "--seconds", "0"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "AVR toolchain" in err and "apt-get install" in err


def test_demo_without_make_is_one_line_exit_2(capsys, monkeypatch):
    from rovernav import demo

    real_which = demo.shutil.which
    monkeypatch.setattr(demo.shutil, "which", lambda name: None if name == "make" else real_which(name))
    monkeypatch.setattr(demo, "check_tools", demo.check_tools)
    if (
        demo.subprocess.run(
            [demo.sys.executable, "tools/build_uno.py", "--check-tools"], cwd=demo.ROOT, capture_output=True
        ).returncode
        != 0
    ):
        pytest.skip("the AVR toolchain is missing here (the previous test covers that)")
    rc, err = run_cli(["demo", "--seconds", "0"], capsys)
    assert rc == 2 and "make" in err and len(err.splitlines()) == 1, err


def test_demo_without_simavr_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    from rovernav import demo

    monkeypatch.setattr(demo, "SIMAVR_HEADER", tmp_path / "sim_avr.h")
    monkeypatch.setattr(demo, "ROOT", tmp_path)  # no bridge built either
    (tmp_path / "tools").mkdir()
    (tmp_path / "tools" / "build_uno.py").write_text("import sys\nsys.exit(0)\n")
    real_which = demo.shutil.which
    monkeypatch.setattr(demo.shutil, "which", lambda name: "/usr/bin/make" if name == "make" else real_which(name))
    rc, err = run_cli(["demo", "--seconds", "0"], capsys)
    assert rc == 2 and "simavr" in err and len(err.splitlines()) == 1, err


def test_a_simulator_that_cannot_load_libsimavr_is_one_line(tmp_path, monkeypatch):
    from rovernav import demo

    bridge = tmp_path / "build" / "avrsim" / "rovernav_avrsim"
    bridge.parent.mkdir(parents=True)
    bridge.write_text(
        "#!/bin/sh\necho 'rovernav_avrsim: error while loading shared libraries: libsimavr.so.1: "
        "cannot open shared object file' >&2\nexit 127\n"
    )
    bridge.chmod(0o755)
    monkeypatch.setattr(demo, "ROOT", tmp_path)
    with pytest.raises(demo.DemoError) as info:
        demo.start_avrsim(tmp_path / "firmware.elf")
    assert "libsimavr" in str(info.value) and "apt-get install libsimavr-dev" in str(info.value)
    assert "\n" not in str(info.value)


def test_a_failed_build_is_one_line_with_its_last_line(monkeypatch):
    from rovernav import demo

    with pytest.raises(demo.DemoError) as info:
        demo._run(
            [demo.sys.executable, "-c", "import sys; print('compiling'); sys.exit('rover.cpp:1: error: boom')"],
            "building the Uno image",
        )
    assert str(info.value).startswith("building the Uno image failed: rover.cpp:1: error: boom")
    assert "\n" not in str(info.value)
    with pytest.raises(demo.DemoError, match="no-such-tool-xyz is not installed"):
        demo._run(["no-such-tool-xyz"], "building")


def test_the_hosts_exceptions_are_one_small_tree():
    # A caller catches what it can handle: input, link, camera, planning, setup, a failed mission.
    from rovernav import errors
    from rovernav.config import ConfigError
    from rovernav.cores import FirmwareBuildError
    from rovernav.cores.uno_harness import UnoSetupError
    from rovernav.demo import DemoError
    from rovernav.evaluation.arenas import GenerationFailed
    from rovernav.link.provision import ProvisionError
    from rovernav.planning import NoPathError, Unreachable
    from rovernav.runlog.replay import LogFileError
    from rovernav.scenario import ScenarioError

    branches = (
        errors.InputError,
        LinkError,
        errors.CameraError,
        errors.PlanningError,
        errors.SetupError,
        errors.MissionFailed,
    )
    assert all(issubclass(b, errors.RovernavError) for b in branches)
    for cls, branch in [
        (ConfigError, errors.InputError),
        (ScenarioError, errors.InputError),
        (MapFileError, errors.InputError),
        (LogFileError, errors.InputError),
        (PortSpecError, errors.InputError),
        (PortSpecError, LinkError),
        (ProvisionError, LinkError),
        (NoPathError, errors.PlanningError),
        (Unreachable, errors.PlanningError),
        (GenerationFailed, errors.PlanningError),
        (DemoError, errors.SetupError),
        (FirmwareBuildError, errors.SetupError),
        (UnoSetupError, errors.SetupError),
    ]:
        assert issubclass(cls, branch), (cls, branch)
        assert sum(issubclass(cls, b) for b in branches) == (2 if cls is PortSpecError else 1), cls
