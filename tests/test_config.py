"""The host's TOML configuration, and `rovernav run`'s errors for a missing port, a missing
camera and a rover built from another protocol definition."""

from __future__ import annotations

import subprocess
import sys
import threading

import cv2
import numpy as np
import pytest
from tests.core_transport import firmware_hello

from rovernav import vehicle_gen as vehicle
from rovernav.config import ConfigError, config_from_dict, load_config
from rovernav.link import framing
from rovernav.link import messages_gen as mg
from rovernav.link.transport import PtyTransport


def test_defaults_are_the_seeds_set_up():
    cfg = load_config(None)
    assert (cfg.arena.width_m, cfg.arena.height_m) == (
        vehicle.DEFAULT_ARENA_WIDTH_MM / 1000,
        vehicle.DEFAULT_ARENA_HEIGHT_MM / 1000,
    )
    assert cfg.link.baud == vehicle.LINK_BAUD
    assert cfg.vision.markers == "colour" and cfg.vision.hsv.rover_back == ((55, 50, 50), (80, 255, 255))
    assert cfg.planner.resolution_m == 0.03 and cfg.planner.robot_radius_m == 0.12


def test_a_full_file_is_read(tmp_path):
    f = tmp_path / "rover.toml"
    f.write_text(
        '[arena]\nwidth_m = 3.0\nheight_m = 2\n[link]\nport = "/dev/ttyUSB0"\n'
        '[rover]\ndrive_pwm = 90\nsweep_interval_mm = 250\n[vision]\nmarkers = "aruco"\n'
    )
    cfg = load_config(f)
    assert cfg.arena.width_m == 3.0 and cfg.arena.height_m == 2.0
    assert dict(cfg.rover_params()) == {mg.Param.DRIVE_PWM: 90, mg.Param.SWEEP_INTERVAL_MM: 250}
    assert cfg.vision.markers == "aruco"


@pytest.mark.parametrize(
    "data, words",
    [
        ({"arena": {"width_m": -1}}, "[arena] width_m"),
        ({"arena": {"depth_m": 1}}, "no key 'depth_m'"),
        ({"link": {"baud": 12345}}, "[link] baud"),
        ({"rover": {"drive_pwm": 300}}, "drive_pwm = 300 is outside [0, 255]"),
        ({"rover": {"warp_speed": 9}}, "no parameter 'warp_speed'"),
        ({"rover": {"drive_pwm": 1.5}}, "should be an integer"),
        ({"vision": {"markers": "lasers"}}, "vision.markers"),
        ({"planner": {"resolution_m": -0.1}}, "[planner]"),
        ({"warp": {}}, "unknown section [warp]"),
        # The sensor's facts, once (protocol/vehicle.toml): no report range past what
        # the HC-SR04 driver measures, no beam wider than the rover's parameter takes.
        ({"rover": {"sonar_report_mm": 4000}}, "sonar_report_mm = 4000 is outside [50, 1000]"),
        ({"planner": {"sonar_max_range_m": 4.0}}, "sonar_max_range_m is gone: the sensor's range is the protocol's"),
        ({"planner": {"sonar_cone_deg": 120}}, "sonar_cone_deg must be 1-90"),
    ],
)
def test_a_bad_value_names_its_section_and_key(data, words):
    with pytest.raises(ConfigError) as exc:
        config_from_dict(data, where="rover.toml: ")
    assert words in str(exc.value) and str(exc.value).startswith("rover.toml: ")


def test_unreadable_files_are_refused_clearly(tmp_path):
    with pytest.raises(ConfigError, match="missing.toml: no such configuration file"):
        load_config(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="is a folder, not a configuration file"):
        load_config(tmp_path)
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'[camera]\nsource = "c\xe1mara"\n')
    with pytest.raises(ConfigError, match="not a UTF-8 text file"):
        load_config(latin)
    bad = tmp_path / "bad.toml"
    bad.write_text("[arena\nwidth_m = 2")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)


def _rovernav(*args, timeout=60):
    return subprocess.run(
        [sys.executable, "-m", "rovernav.cli", *args], capture_output=True, text=True, timeout=timeout
    )


def test_run_with_a_missing_camera_or_port_fails_with_a_message(tmp_path):
    r = _rovernav("run", "--port", "/dev/ttyUSB0", "--camera", str(tmp_path / "nocam.mp4"))
    assert r.returncode == 2 and "no such file" in r.stderr and "Traceback" not in r.stderr
    video = _video(tmp_path / "arena.mp4")
    r = _rovernav("run", "--port", "/dev/ttyNOPE9", "--camera", str(video))
    assert r.returncode == 2 and "/dev/ttyNOPE9" in r.stderr and "Traceback" not in r.stderr


def _video(path):
    from rovernav.sim.camera import Renderer, Scene

    r = Renderer(seed=0)
    rng = np.random.default_rng(0)
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, (640, 480))
    for _ in range(150):
        out.write(r.render(Scene(rover=(0.3, 0.3, 0.0), target=(2.0, 1.4)), rng))
    out.release()
    return path


def test_run_refuses_a_rover_built_from_another_protocol_definition(tmp_path):
    video = _video(tmp_path / "arena.mp4")
    with PtyTransport() as rover_end:
        stop = threading.Event()

        def fake_rover():
            dec = framing.FrameDecoder()
            while not stop.is_set():
                for f in dec.feed(rover_end.read(4096, 0.05)):
                    if isinstance(f.message, mg.Hello):
                        rover_end.write(framing.encode_frame(firmware_hello(schema_hash=0xBADC0DE5, boot_id=7), 0))

        t = threading.Thread(target=fake_rover, daemon=True)
        t.start()
        try:
            r = _rovernav(
                "run",
                "--port",
                rover_end.peer_name,
                "--camera",
                str(video),
                "--scenario",
                "seed-fig4-8-unknown-obstacle",
                "--log",
                str(tmp_path / "refused.mcap"),
                timeout=90,
            )
        finally:
            stop.set()
            t.join(2)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "0xBADC0DE5" in r.stderr and f"0x{mg.SCHEMA_HASH:08X}" in r.stderr
    # The run's log is kept, with the rover's HELLO that ended it.
    from rovernav.runlog.replay import read_log

    said = [r for r in read_log(tmp_path / "refused.mcap").inputs if r["kind"] == "rx"]
    assert said and said[0]["type"] == "hello" and said[0]["fields"]["schema_hash"] == 0xBADC0DE5


def test_the_old_sonar_section_is_refused_naming_where_the_offset_lives():
    from rovernav.config import ConfigError, config_from_dict

    with pytest.raises(ConfigError, match=r"\[planner\] sonar_offset_m"):
        config_from_dict({"sonar": {"offset_m": 0.1}}, where="old.toml: ")


def test_a_report_range_past_the_sensor_s_is_refused_in_one_line_exit_2(tmp_path, capsys):
    from rovernav.cli import main

    f = tmp_path / "far.toml"
    f.write_text("[rover]\nsonar_report_mm = 4000\n")
    assert main(["sim", "--config", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sonar_report_mm = 4000 is outside [50, 1000] (mm)" in err[0]
    assert mg.PARAMS[mg.Param.SONAR_REPORT_MM].max == vehicle.SONAR_MAX_RANGE_MM


def test_the_mission_s_planner_is_chosen_by_configuration():
    from rovernav.mission.spec import MissionSpec
    from rovernav.scenario import load_scenario

    scenario = load_scenario("seed-fig4-8-unknown-obstacle")
    assert load_config(None).mission.planner == "astar"
    assert MissionSpec.for_run(scenario, load_config(None)).planner_name == "astar"
    cfg = config_from_dict({"mission": {"planner": "theta"}})
    assert MissionSpec.for_run(scenario, cfg).planner_name == "theta"
    with pytest.raises(ConfigError, match=r"\[mission\] planner = 'potential' must be one of astar, theta"):
        config_from_dict({"mission": {"planner": "potential"}})


def test_the_fix_rate_is_every_frame_by_default_and_three_within_the_rovers_fix_timeout_when_set():
    assert config_from_dict({}).mission.fix_hz == 0.0
    assert config_from_dict({"mission": {"fix_hz": 10}}).mission.fix_hz == 10.0
    for bad in (2, 5.9, -1, 121):  # the rover's fix_timeout_ms is 500 by default: at least 6 a second
        with pytest.raises(ConfigError, match=r"\[mission\] fix_hz"):
            config_from_dict({"mission": {"fix_hz": bad}}, where="rover.toml: ")
    slow = {"mission": {"fix_hz": 4}, "rover": {"fix_timeout_ms": 1000}}
    assert config_from_dict(slow).mission.fix_hz == 4.0
    with pytest.raises(ConfigError, match=r"at least 15 a second \(3 within the rover's fix_timeout_ms, 200 ms"):
        config_from_dict({"mission": {"fix_hz": 10}, "rover": {"fix_timeout_ms": 200}})
