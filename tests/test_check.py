"""`rovernav check`: a healthy set-up passes every line; each fault, injected one at a time into the
simulated rover, is named by its own line, and the command exits 1."""

from __future__ import annotations

import json

import pytest

from rovernav import check
from rovernav.cli import main
from rovernav.config import config_from_dict

pytestmark = pytest.mark.mission  # each test runs the simulated rover for a few seconds


# The line that must fail for each fault, and words it must say.
FAULT_LINES = {
    "dead-gyro": ("gyro", "gyro_silent: check the MPU6050's wiring"),
    "sonar-unwired": ("sonar", "no echo"),
    "motor-reversed": ("motors", "a motor turns the wrong way"),
    "no-markers": ("camera", "the rover found in 0 of"),
    "radio-loss-20": ("link", "the radio loses most frames"),
}


def test_a_healthy_rover_passes_every_check():
    lines, elapsed = check.check_sim(config_from_dict({}))
    assert [ln.name for ln in lines] == ["link", "camera", "gyro", "sonar", "servo", "motors"]
    assert all(ln.status == "ok" for ln in lines), [str(ln) for ln in lines]
    assert elapsed < check.PROBE_TIME_S


@pytest.mark.parametrize("fault", check.FAULTS)
def test_each_fault_is_named_by_its_own_line(fault):
    lines, _ = check.check_sim(config_from_dict({}), fault=fault)
    failed = [ln for ln in lines if ln.status == "FAIL"]
    name, words = FAULT_LINES[fault]
    assert [ln.name for ln in failed] == [name], [str(ln) for ln in lines]
    assert words in failed[0].text and "\n" not in failed[0].text


def test_the_command_s_exit_statuses_and_json(capsys):
    assert main(["check", "--sim"]) == 0
    assert "every check passed (6)" in capsys.readouterr().out
    assert main(["check", "--sim", "--fault", "sonar-unwired", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["passed"] is False and {c["name"]: c["status"] for c in out["checks"]}["sonar"] == "FAIL"
    assert main(["check"]) == 2  # neither --port nor --sim
    assert main(["check", "--port", "loop://", "--fault", "dead-gyro"]) == 2
    capsys.readouterr()
    assert main(["check", "--port", "/dev/ttyUSB9", "--camera", "no-such-video.mp4"]) == 2  # before any device opens
    assert "no-such-video.mp4" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["check", "--sim", "--fault", "everything"])
    assert exc.value.code == 2


def test_a_set_up_checks_with_its_calibrated_configuration_and_not_without(tmp_path, capsys):
    assert main(["sim", "seed-small-obstacles", "--setup", "7008", "--calibration-frames", str(tmp_path)]) == 0
    command = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("calibrate:")).split()[3:]
    assert main(["calibrate", *command, "--picture", str(tmp_path / "c.png")]) == 0
    capsys.readouterr()
    assert main(["check", "--sim", "--setup", "7008", "--config", str(tmp_path / "calibrated.toml")]) == 0
    capsys.readouterr()
    assert main(["check", "--sim", "--setup", "7008", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert {c["name"]: c["status"] for c in out["checks"]}["camera"] == "FAIL"


def test_the_real_rover_path_over_a_serial_port_names_the_uno_image_s_missing_gyro(built, tmp_path, capsys):
    # `rovernav check --port` end to end: the Uno image in simavr behind a pseudo-terminal (the
    # bridge simulates no MPU6050) and a video file for the camera (a still scene, rover in view).
    from test_avrsim import still_video, uno_on_a_pty

    video = still_video(tmp_path / "still.avi", (1.0, 0.9, 90.0), (2.0, 1.4), 300)
    with uno_on_a_pty(built, tmp_path / "bridge.log", 60) as port:
        assert main(["check", "--port", port, "--camera", str(video), "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    status = {c["name"]: (c["status"], c["text"]) for c in result["checks"]}
    assert status["link"][0] == "ok" and "unsigned" in status["link"][1], status["link"]
    assert status["camera"][0] == "ok"
    assert status["gyro"][0] == "FAIL" and "gyro_silent" in status["gyro"][1]
    assert status["motors"] == ("not checked", "the rover stops on a gyro fault")
