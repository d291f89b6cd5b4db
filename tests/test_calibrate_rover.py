"""`rovernav calibrate rover`: the motors' figures fitted from runs the camera watches."""

from __future__ import annotations

import json
import random

import pytest

from rovernav.calibrate import rover as cr
from rovernav.cli import main
from rovernav.config import config_from_dict, load_config
from rovernav.link import messages_gen as mg
from rovernav.sim.setup import Setup, true_vision

DRIVE = int(mg.RoverState.DRIVE)


def synthetic_run(level: int, k: float, d: float, g: float, hz: float = 30.0, drive_s: float = 4.0) -> cr.Run:
    """A run as a rover of speed k mm/s per PWM above dead band d, its right motor g times the
    left's, would give: straight along +x, the commands that hold it straight."""
    left = float(level)
    right = d + (left - d) / g
    v = k * (left - d) / 1000.0
    run = cr.Run(level, (0.5, 1.0), (1.0, 1.0))
    for i in range(int(drive_s * hz)):
        t = 1.0 + i / hz
        run.poses.append((t, 0.5 + v * (t - 1.0), 1.0, 90.0))
    for i in range(int(drive_s * 10)):
        t = 1.0 + i / 10
        # Whole PWM, dithered round the true command as the PID does.
        run.status.append((t, DRIVE, int(left), int(right) + (1 if (i * (right % 1)) % 1 > 0.5 else 0), 9000))
    return run


def test_the_fit_recovers_the_motor_figures_it_was_made_from():
    runs = [synthetic_run(level, 2.3, 34.0, 1.12) for level in cr.LEVELS_PWM]
    f = cr.fit(runs)
    assert f.mm_s_per_pwm == pytest.approx(2.3, rel=0.01)
    assert f.deadband_pwm == pytest.approx(34.0, abs=0.5)
    assert f.right_gain == pytest.approx(1.12, rel=0.03)
    assert f.gyro_scale is None and f.gyro_turns == 0  # no run turned round first
    assert f.params() == {
        mg.Param.SPEED_MM_S_PER_PWM_X1000: round(1000 * f.mm_s_per_pwm),
        mg.Param.MOTOR_DEADBAND_PWM: round(f.deadband_pwm),
        mg.Param.RIGHT_BIAS_PERMILLE: round(1000 / f.right_gain),
    }


@pytest.mark.parametrize(
    "runs, reason",
    [
        ([synthetic_run(60, 2.3, 34.0, 1.0)], "fewer than two runs"),
        ([cr.Run(60, (0, 0), (1, 0)), cr.Run(80, (0, 0), (1, 0))], "the camera never found the rover"),
        (
            [
                cr.Run(60, (0, 0), (1, 0), poses=[(1.0, 0.0, 0.0, 90.0)]),
                cr.Run(80, (0, 0), (1, 0), poses=[(1.0, 0.0, 0.0, 90.0)]),
            ],
            "never drove",
        ),
        (
            [synthetic_run(60, 2.3, 34.0, 1.0, drive_s=0.9), synthetic_run(80, 2.3, 34.0, 1.0, drive_s=0.9)],
            "drove steadily for",
        ),
        (
            [synthetic_run(60, 2.3, 34.0, 1.0, hz=3.0), synthetic_run(80, 2.3, 34.0, 1.0, hz=3.0)],
            "the camera saw the rover",
        ),
    ],
)
def test_runs_that_cannot_be_fitted_are_refused_with_the_reason(runs, reason):
    with pytest.raises(cr.CalibrationFailed, match=reason):
        cr.fit(runs)


def test_speeds_that_do_not_rise_with_the_command_are_refused():
    slow = synthetic_run(60, 2.3, 34.0, 1.0)
    fast = synthetic_run(80, 2.3, 34.0, 1.0)
    fast.poses = [(t, 0.5 + (x - 0.5) * 0.3, y, h) for t, x, y, h in fast.poses]  # slower at the higher command
    with pytest.raises(cr.CalibrationFailed, match="no faster at higher commands"):
        cr.fit([slow, fast])


def test_in_the_simulator_a_set_up_s_motors_are_recovered_within_5_per_cent():
    setup = Setup.random(9101)  # a seed nothing was tuned on
    cfg = config_from_dict(
        {"arena": {"width_m": 2.36, "height_m": 1.75}, "vision": true_vision(setup, 2.36, 1.75).to_dict()}
    )
    f = cr.fit(cr.runs_sim(cfg, setup=setup))
    p = setup.plant
    assert f.mm_s_per_pwm == pytest.approx(p.mm_s_per_pwm, rel=0.05)
    assert f.deadband_pwm == pytest.approx(p.deadband_pwm, rel=0.05)
    assert f.right_gain == pytest.approx(p.right_gain, rel=0.05)
    assert f.gyro_turns == 3  # every run turns round first: the first from the bench's wall
    assert f.gyro_scale == pytest.approx(p.gyro_scale, rel=0.05)
    assert abs(f.gyro_scale - p.gyro_scale) < abs(1.0 - p.gyro_scale) or abs(1.0 - p.gyro_scale) < 0.01


def test_in_the_simulator_the_gyro_bias_and_the_sonar_offset_are_recovered():
    setup = Setup.random(9102)  # a seed nothing was tuned on
    cfg = config_from_dict(
        {"arena": {"width_m": 2.36, "height_m": 1.75}, "vision": true_vision(setup, 2.36, 1.75).to_dict()}
    )
    runs = cr.runs_sim(cfg, setup=setup)
    f = cr.fit(runs, cr.sim_bench(cfg)[2])
    first = runs[0]
    t0, t1 = first.still_window()
    # START waited for the still window, and no fix went to the rover in it.
    assert first.start_sent_s >= t1
    truth = [b for t, b in first.true_bias if t0 + cr.BIAS_SKIP_S <= t <= t1]
    assert len(truth) >= 30
    true_bias = sum(truth) / len(truth)
    assert abs(true_bias) > 0.02  # a bias worth measuring (this set-up's first run: 0.05 deg/s)
    assert f.gyro_bias[0] == pytest.approx(true_bias, abs=0.01)
    assert f.gyro_bias[1] < 0.005
    offset_m, spread_m, echoes = f.sonar
    assert abs(setup.plant.sonar_offset_m - 0.100) > 0.01  # not the configuration's default
    assert offset_m == pytest.approx(setup.plant.sonar_offset_m, abs=0.005)
    assert echoes >= 4 and spread_m < 0.03  # two sweeps (the first and third runs)
    assert f.planner() == {"sonar_offset_m": round(offset_m, 3)}


def facing_wall_run(offset_m: float, centre_m: float, heading_deg: float, bearings=range(-60, 61, 10)) -> cr.Run:
    """A run that swept a wall whose face is the line x = 1.0 (from y 0.5 to 1.5), the rover's
    centre centre_m from it at y 1.0, heading_deg (90: square to it), its ranger offset_m ahead;
    a flat wall's echo is the nearest point in the 15 degree cone."""
    import math

    run = cr.Run(60, (0.5, 1.0), (0.0, 1.0), swept=True)
    x = 1.0 - centre_m
    run.poses = [(0.05 * k, x, 1.0, heading_deg) for k in range(60)]
    sensor = centre_m - offset_m * math.cos(math.radians(heading_deg - 90.0))
    for k, b in enumerate(bearings):
        off = abs(heading_deg + b - 90.0)
        if off <= 7.5:
            r = sensor
        elif off < 60:
            r = sensor / math.cos(math.radians(off - 7.5))
        else:
            continue
        run.echoes.append((1.0 + 0.1 * k, float(b), r))
    return run


WALL = (1.0, 0.5, 1.0, 1.5)


@pytest.mark.parametrize("heading_deg", [90.0, 80.0, 104.0])
def test_the_sonar_offset_is_the_distance_to_the_wall_less_the_echoes_square_to_it(heading_deg):
    got = cr.sonar_offset([facing_wall_run(0.083, 0.40, heading_deg), facing_wall_run(0.083, 0.45, heading_deg)], WALL)
    offset_m, spread_m, echoes = got
    assert offset_m == pytest.approx(0.083, abs=1e-6) and spread_m < 1e-6
    assert echoes >= 2


@pytest.mark.parametrize(
    "run, says",
    [
        (facing_wall_run(0.08, 0.4, 135.0), "degrees off square to the wall"),
        (cr.Run(60, (0, 0), (1, 0), swept=True), "the sweep reported no echo"),
        (facing_wall_run(0.08, 0.4, 90.0, bearings=(-40, 40)), "no echo square to the wall"),
    ],
)
def test_a_sweep_that_gives_no_offset_says_why(run, says):
    assert says in cr.sonar_offset([run], WALL)


def test_a_rover_past_the_wall_s_end_is_not_in_front_of_it():
    run = facing_wall_run(0.08, 0.4, 90.0)
    run.poses = [(t, x, 2.0, h) for t, x, y, h in run.poses]
    assert "not in front of the wall" in cr.sonar_offset([run], WALL)


@pytest.mark.parametrize(
    "pose, says",
    [
        ((0.6, 1.0, 160.0), "degrees off square"),
        ((0.2, 1.0, 90.0), "stand it 0.15-0.50 m from the wall"),
        ((0.95, 1.0, 90.0), "stand it 0.15-0.50 m from the wall"),
        ((0.6, 1.8, 90.0), "not in front of the wall"),
    ],
)
def test_the_real_rover_must_stand_facing_the_wall_near_it(pose, says):
    with pytest.raises(cr.CalibrationFailed, match=says):
        cr.check_wall(WALL, *pose, sonar_offset_m=0.1)
    cr.check_wall(WALL, 0.6, 1.0, 95.0, sonar_offset_m=0.1)


def test_the_gyro_bias_is_the_heading_s_drift_in_the_still_window_the_camera_seeing_it_still():
    run = cr.Run(60, (0, 0), (1, 0), still_s=cr.STILL_S)
    run.fixed_at_s = 2.0
    t0, t1 = run.still_window()
    assert run.hold_start(t0) and run.hold_start(t1 - 0.01) and not run.hold_start(t1)
    assert run.withhold(t0) and not run.withhold(t0 - 0.01) and not run.withhold(t1)
    # The rover's heading drifts 0.12 deg/s (whole centidegrees, as STATUS says it) across 180;
    # the camera sees the rover still, its headings noisy by 0.3 degrees.
    rng = random.Random(4)
    run.status = [
        (t0 + 0.2 * k, 0, 0, 0, round(100 * (179.5 + 0.12 * 0.2 * k + 180) % 36000 - 18000))
        for k in range(int(cr.STILL_S / 0.2))
    ]
    run.poses = [(t0 + k / 30, 0.5, 0.5, 90.0 + rng.gauss(0, 0.3)) for k in range(int(cr.STILL_S * 30))]
    bias, se = run.gyro_bias()
    assert bias == pytest.approx(0.12, abs=0.002) and se < 0.002
    # A rover the camera saw turn 3 degrees was not still.
    run.poses = [(t, x, y, h + 3.0 * (t - t0) / cr.STILL_S) for t, x, y, h in run.poses]
    assert "the camera saw the rover turn +2.6 degrees" in run.gyro_bias()  # medians of the first and last second
    assert cr.Run(60, (0, 0), (1, 0)).gyro_bias() is None  # no still window


def test_the_command_fits_the_simulated_rover_and_writes_rover_keeping_the_rest(tmp_path, capsys):
    conf = tmp_path / "rover.toml"
    conf.write_text("# mine\n[arena]\nwidth_m = 2.36\nheight_m = 1.75\n\n[rover]\ndrive_pwm = 75 # kept\n")
    assert main(["calibrate", "rover", "--sim", "--write", str(conf), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["written"] == str(conf)
    assert len(out["runs"]) == len(cr.LEVELS_PWM)
    text = conf.read_text()
    assert "# mine" in text and "drive_pwm = 75 # kept" in text
    cfg = load_config(conf)
    # The default plant: 2.2 mm/s per PWM above 30, the right motor 1.10 x the left.
    assert cfg.rover[mg.Param.SPEED_MM_S_PER_PWM_X1000] == pytest.approx(2200, rel=0.05)
    assert cfg.rover[mg.Param.MOTOR_DEADBAND_PWM] == pytest.approx(30, abs=2)
    assert cfg.rover[mg.Param.RIGHT_BIAS_PERMILLE] == pytest.approx(1000 / 1.10, rel=0.05)
    assert cfg.rover[mg.Param.DRIVE_PWM] == 75
    # The bench's wall gives the sonar's offset (the default plant's 100 mm), written in [planner].
    assert out["sonar_echoes"] >= 4
    assert cfg.planner.sonar_offset_m == pytest.approx(0.100, abs=0.005) == out["planner"]["sonar_offset_m"]
    assert out["gyro_bias_dps"] is not None and abs(out["gyro_bias_dps"]) < 0.2


def test_the_command_says_each_figure_in_a_line(capsys):
    assert main(["calibrate", "rover", "--sim"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum(line.startswith("run ") for line in lines) == 3
    assert any(line.startswith("gyro     bias left after its start-up measure") for line in lines)
    assert any(line.startswith("sonar    ") and "ahead of the rover's centre" in line for line in lines)
    assert any(line.startswith("param    [planner] sonar_offset_m = ") for line in lines)
    assert "sonar_offset_m = " in lines[-1]


def test_a_set_up_the_configuration_cannot_see_is_named(capsys):
    # The default configuration's marker colours are not set-up 5's: the runs never start.
    assert main(["calibrate", "rover", "--sim", "--setup", "5"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert any("--setup without --config" in line for line in err)
    assert err[-1] == (
        "rovernav calibrate rover: could not calibrate: fewer than two runs to fit a line through "
        "(every run: the camera never found the rover (calibrate the camera first: rovernav "
        "calibrate camera))"
    )


@pytest.mark.parametrize(
    "argv, says",
    [
        (["calibrate", "rover"], "give the rover's --port"),
        (["calibrate", "rover", "--setup", "3"], "give the rover's --port"),
        (["calibrate", "rover", "--port", "/dev/null", "--setup", "3"], "--setup is a simulated set-up"),
        (["calibrate", "rover", "--sim", "--camera", "0"], "--camera watches the real rover"),
        (["calibrate", "rover", "--sim", "--config", "/no/such.toml"], "no such configuration file"),
        (["calibrate", "rover", "--sim", "--port", "x"], "not allowed with argument"),
        (["calibrate", "rover", "--port", "x", "--wall", "1,2,3"], "give the wall's face as X0,Y0,X1,Y1"),
        (["calibrate", "rover", "--port", "x", "--wall", "1,2,1.1,2"], "less than 0.2 m apart"),
        (["calibrate", "rover", "--port", "x", "--wall", "1,nan,1,2"], "give the wall's face"),
        (["calibrate", "rover", "--port", "x", "--wall", "9,0,9,1"], "is not in the"),
        (["calibrate", "rover", "--sim", "--wall", "1,0,1,1"], "the simulator's bench has its own"),
    ],
)
def test_the_command_refuses_bad_input_in_one_line_exit_2(argv, says, capsys):
    with pytest.raises(SystemExit) as e:
        code = main(argv)
        raise SystemExit(code)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert says in err[-1]


def test_runs_need_room_ahead_of_the_rover():
    with pytest.raises(cr.CalibrationFailed, match="turn the rover to face"):
        cr.check_room((2.2, 0.9), 90.0, 2.36, 1.75, 0.16)
    cr.check_room((0.8, 0.9), 90.0, 2.36, 1.75, 0.16)


def test_the_real_rover_path_over_a_serial_port_says_why_the_uno_image_gave_no_runs(built, tmp_path, capsys):
    # `rovernav calibrate rover --port` end to end: the Uno image in simavr behind a
    # pseudo-terminal (the bridge simulates no MPU6050, so the rover faults and never drives) and
    # a video file for the camera (a still scene, the rover facing open floor).
    from test_avrsim import still_video, uno_on_a_pty

    video = still_video(tmp_path / "still.avi", (0.8, 0.9, 90.0), (2.0, 1.4), 600)
    with uno_on_a_pty(built, tmp_path / "bridge.log", 90) as port:
        assert main(["calibrate", "rover", "--port", port, "--camera", str(video)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("rovernav calibrate rover: could not calibrate: fewer than two runs")
    assert "gyro_silent" in err[-1], err[-1]
