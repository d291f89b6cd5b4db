"""`rovernav run --rovers N` (issue 30): a fleet with one camera and one radio. Three rover cores
(each provisioned as rover k of a fleet, with its own key) stand behind one fake serial port and
a fake camera shows their ArUco tags at their berths: every rover is greeted, configured and sent
its first leg, and the run log holds a channel set per rover. Bad inputs: one line, exit 2, no
device opened."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import pytest
from tests.core_transport import FleetCoreTransport

from rovernav import hardware
from rovernav.cli import main
from rovernav.cores import NativeCore
from rovernav.link.keys import write_key_file
from rovernav.scenario import load_scenario

SCENARIO = str(Path(__file__).resolve().parents[1] / "scenarios" / "fleet-out-and-back.toml")


class _Camera:
    """The overhead camera: the rovers standing at their berths, each with its tag (30 frames a second)."""

    def __init__(self, scenario, tags: dict[int, int]):
        from rovernav.config import config_from_dict
        from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene

        vision = dataclasses.replace(config_from_dict({}).vision, markers="aruco")
        self.rng = np.random.default_rng(1)
        self.renderer = Renderer(RoverLook.for_vision(vision), Camera(lighting=Lighting(), noise_sigma=2.0), 1)
        poses = [(s.x_m, s.y_m, s.heading_deg) for s in scenario.starts[: len(tags)]]
        fleet = tuple((*poses[k - 1], tags[k]) for k in range(2, len(tags) + 1))
        self.scene = dataclasses.replace(Scene.of_scenario(scenario, "aruco"), rover=poses[0], fleet=fleet)

    def read(self):
        time.sleep(1 / 30)
        return True, self.renderer.render(self.scene, self.rng)

    def release(self):
        pass


@pytest.mark.mission
def test_a_fleet_run_greets_configures_and_starts_every_rover_and_logs_each(tmp_path, monkeypatch, capsys):
    from rovernav.vision.fleet import fleet_tags

    keys = [tmp_path / f"rover{k}.key" for k in (1, 2, 3)]
    cores = [NativeCore(boot_id=100 + k, key=write_key_file(f), fleet_id=k + 1) for k, f in enumerate(keys)]
    monkeypatch.setattr(hardware, "SerialTransport", lambda name, baud: FleetCoreTransport(cores))
    camera = _Camera(load_scenario(SCENARIO), fleet_tags(3))
    monkeypatch.setattr(hardware, "open_camera", lambda source: camera)
    log = tmp_path / "fleet.mcap"
    code = main(
        ["run", "--rovers", "3", "--port", "/dev/ttyFAKE", "--camera", "0", "--scenario", SCENARIO]
        + ["--key-files", *map(str, keys), "--max-time", "6", "--log", str(log)]
    )
    out = capsys.readouterr()
    assert code == 1  # stopped by --max-time, the trips not done
    assert "rover 1 tag 1, rover 2 tag 3, rover 3 tag 4" in out.out
    from mcap.reader import make_reader

    sent: dict[str, set] = {}
    with open(log, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            if channel.topic.endswith("/link/host_to_rover"):
                sent.setdefault(channel.topic.split("/")[1], set()).add(json.loads(message.data)["type"])
    for k in (1, 2, 3):
        # Each rover heard its HELLO, its parameters, and its first leg's path and START.
        assert {"hello", "config", "path", "start"} <= sent.get(f"rover{k}", set()), (k, sent)
    for core in cores:
        core.close()


@pytest.mark.parametrize(
    "args, says",
    [
        (["--rovers", "3"], "--rovers needs --scenario"),
        (["--rovers", "5", "--scenario", SCENARIO], ">= 2 and <= 4"),
        (["--rovers", "3", "--scenario", SCENARIO, "--key-files", SCENARIO], "1 files for 3 rovers"),
        (["--rovers", "3", "--scenario", SCENARIO, "--map", "m.json"], "--map is for one rover"),
        (["--trips", "2", "--scenario", SCENARIO], "--trips is for a fleet"),
        (["--rover-configs", SCENARIO, "--scenario", SCENARIO], "--rover-configs is for a fleet"),
        (["--rovers", "2", "--scenario", SCENARIO, "--rover-configs", SCENARIO], "1 files for 2 rovers"),
        (["--rovers", "2", "--scenario", SCENARIO, "--rover-configs", SCENARIO, SCENARIO], "unknown section [name]"),
    ],
)
def test_a_bad_fleet_run_is_one_line_and_opens_no_device(args, says, monkeypatch, capsys):
    def no_device(*a, **k):
        raise AssertionError("a device was opened")

    monkeypatch.setattr(hardware, "SerialTransport", no_device)
    monkeypatch.setattr(hardware, "open_camera", no_device)
    try:
        code = main(["run", "--port", "/dev/ttyFAKE", "--camera", "0", *args])
    except SystemExit as exc:  # argparse's own refusal of a flag's value
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and says in err and err.count("\n") == 1, err


def test_each_rover_of_a_fleet_is_sent_its_own_parameters(tmp_path, capsys):
    mine = tmp_path / "rover1.toml"
    mine.write_text("[rover]\nmotor_deadband_pwm = 33\nspeed_mm_s_per_pwm_x1000 = 2400\n")
    plain = tmp_path / "rover2.toml"
    plain.write_text("")
    out = tmp_path / "out"
    code = main(
        ["sim", "fleet-out-and-back", "--rovers", "2", "--trips", "1", "--max-time", "3", "--no-video", "--quiet"]
        + ["--out", str(out), "--rover-configs", str(mine), str(plain)]
    )
    assert code == 1  # stopped by --max-time
    from mcap.reader import make_reader

    from rovernav.link import messages_gen as mg

    said: dict[str, dict] = {"rover1": {}, "rover2": {}}
    with open(out / "run.mcap", "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            if channel.topic.endswith("/link/host_to_rover"):
                m = json.loads(message.data)
                if m["type"] == "config":
                    said[channel.topic.split("/")[1]][m["fields"]["param"]] = m["fields"]["value"]
    deadband, speed = int(mg.Param.MOTOR_DEADBAND_PWM), int(mg.Param.SPEED_MM_S_PER_PWM_X1000)
    assert said["rover1"].get(deadband) == 33 and said["rover1"].get(speed) == 2400
    assert deadband not in said["rover2"] and speed not in said["rover2"]  # the defaults: not sent
    assert said["rover1"][int(mg.Param.SWEEP_STEP_MS)] == said["rover2"][int(mg.Param.SWEEP_STEP_MS)] == 400


def test_a_rover_config_may_not_set_the_fleets_share_of_the_air(tmp_path, capsys):
    mine = tmp_path / "rover1.toml"
    mine.write_text("[rover]\nsweep_step_ms = 100\n")
    code = main(
        ["sim", "fleet-out-and-back", "--rovers", "2", "--no-video", "--no-log", "--max-time", "1"]
        + ["--out", str(tmp_path / "out"), "--rover-configs", str(mine), str(mine)]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "sweep_step_ms is the fleet's to set" in err


@pytest.mark.parametrize(
    "fleet, rover, says",
    [
        ("", "[rover]\nsonar_offset_mm = 80\n", "sonar_offset_mm is the planner's geometry"),
        ("", "[planner]\nsonar_offset_m = 0.085\n", "sonar_offset_m = 0.085 m, the fleet's configuration 0.1 m"),
        ("[rover]\npose_k_rho_x1000 = 1400\n", "[rover]\npose_k_alpha_x1000 = 600\n", "over the fleet's configuration"),
    ],
)
def test_a_rover_config_that_disagrees_with_the_fleets_is_one_line(tmp_path, capsys, fleet, rover, says):
    fleet_file, rover_file = tmp_path / "fleet.toml", tmp_path / "rover1.toml"
    fleet_file.write_text(fleet)
    rover_file.write_text(rover)
    code = main(
        ["sim", "fleet-out-and-back", "--rovers", "2", "--no-video", "--no-log", "--max-time", "1"]
        + [
            "--config",
            str(fleet_file),
            "--out",
            str(tmp_path / "out"),
            "--rover-configs",
            str(rover_file),
            str(fleet_file),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and says in err, err


def test_a_rover_config_whose_sonar_is_where_the_fleets_is_is_taken(tmp_path):
    from rovernav.fleet.run import fleet_rover_params
    from rovernav.link import messages_gen as mg

    rover_file = tmp_path / "rover1.toml"
    rover_file.write_text("[planner]\nsonar_offset_m = 0.103\n[rover]\nmotor_deadband_pwm = 31\n")
    own = fleet_rover_params([str(rover_file)], 1)
    assert own == ({mg.Param.MOTOR_DEADBAND_PWM: 31},)  # 3 mm off the fleet's sonar: within the slack
