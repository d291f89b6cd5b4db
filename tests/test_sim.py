"""The simulator: plant, sensors, world geometry, radio, and whole missions on the shared scenarios."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from rovernav.scenario import load_scenario
from rovernav.sim.channel import Channel, ChannelConfig
from rovernav.sim.plant import PlantConfig, RoverPlant
from rovernav.sim.report import build_report
from rovernav.sim.runner import SimOptions, Simulation
from rovernav.sim.world import Box, World


def _plant(**kw) -> RoverPlant:
    cfg = PlantConfig(**({"speed_noise": 0.0, "gyro_noise_dps": 0.0, "gyro_bias_dps": 0.0,
                          "gyro_bias_walk_dps_per_sqrt_s": 0.0} | kw))
    return RoverPlant(1.0, 1.0, 0.0, cfg, np.random.default_rng(0))


# ---------------------------------------------------------------- plant

def test_plant_speed_follows_pwm_above_the_dead_band_through_a_first_order_lag():
    p = _plant(right_gain=1.0)
    for _ in range(8):  # one lag constant (0.08 s)
        p.step(100, 100, 0, 0.01)
    v_tau = 0.5 * (p.v_left + p.v_right)
    for _ in range(200):
        p.step(100, 100, 0, 0.01)
    v_end = 0.5 * (p.v_left + p.v_right)
    assert v_end == pytest.approx((100 - 30) * 2.2 / 1000, rel=0.01)
    assert 0.55 < v_tau / v_end < 0.7   # 1 - 1/e after one time constant
    assert p.heading == pytest.approx(0.0, abs=1e-6) and p.y > 1.0


def test_plant_does_not_move_inside_the_dead_band():
    p = _plant()
    for _ in range(100):
        p.step(25, -25, 0, 0.01)
    assert (p.x, p.y, p.heading) == (1.0, 1.0, 0.0)


def test_the_stronger_right_motor_turns_the_rover_left_at_equal_commands():
    p = _plant(right_gain=1.10)
    for _ in range(200):
        p.step(80, 80, 0, 0.01)
    assert p.heading < -5.0  # anticlockwise


def test_gyro_reads_the_true_rate_with_noise_and_bias_and_can_die():
    cfg = PlantConfig(gyro_noise_dps=0.05, gyro_bias_dps=0.05)
    p = RoverPlant(1.0, 1.0, 0.0, cfg, np.random.default_rng(4))
    samples = np.array([p.gyro_mdps() for _ in range(2000)]) / 1000
    assert abs(samples.mean() - p.gyro_bias) < 0.005
    assert samples.std() == pytest.approx(0.05, rel=0.1)
    p.gyro_alive = False
    assert p.gyro_mdps() is None


def test_servo_travels_at_0_1_s_per_60_degrees():
    p = _plant()
    steps = 0
    while p.servo_deg > -60.0 + 1e-9:
        p.step(0, 0, -6000, 0.01)
        steps += 1
    assert steps == 10


# ---------------------------------------------------------------- sonar and world

def test_sonar_sees_the_nearest_surface_inside_its_cone_only():
    world = World(3.0, 3.0, [Box(1.0, 1.4, 0.2, 0.1)])   # face at y = 1.35
    p = _plant(sonar_noise_mm=0.0)
    assert p.sonar_mm(world) == pytest.approx(250, abs=2)   # sensor at y = 1.10
    p.x = 1.0 + 0.1 + 0.25 * math.tan(math.radians(5))        # the box's edge 5 degrees off axis
    assert p.sonar_mm(world) < 400
    p.x = 1.0 + 0.1 + 0.25 * math.tan(math.radians(20))       # well outside the 7.5-degree half cone
    assert p.sonar_mm(world) > 600                              # only the floor


def test_sonar_hears_the_floor_beyond_about_0_65_m():
    world = World(5.0, 5.0, [])
    p = _plant()
    p.x, p.y = 2.5, 1.0
    assert 650 <= p.sonar_mm(world) < 900


def test_footprint_contact_and_clearance():
    world = World(2.0, 2.0, [Box(1.0, 1.0, 0.2, 0.2)])
    assert world.clearance_m(1.0, 1.3, 0.0) == pytest.approx(0.095, abs=1e-6)   # nose 0.105 ahead
    assert world.collides(1.0, 1.2, 0.0)
    assert world.collides(0.05, 1.5, 0.0)   # through the wall
    assert world.clearance_bound_m(1.0, 1.5) <= world.clearance_m(1.0, 1.5, 37.0)


# ---------------------------------------------------------------- radio

def test_channel_carries_bytes_at_the_line_rate_after_the_delay():
    ch = Channel(ChannelConfig(delay_s=0.015), np.random.default_rng(0))
    ch.write(bytes(576), 0.0)           # 0.1 s of line time at 5,760 bytes/s
    assert ch.receive(0.015) == b""     # nothing before the delay has passed
    early = len(ch.receive(0.05))       # 35 ms of line time: about 201 bytes
    assert 195 <= early <= 203
    assert early + len(ch.receive(0.2)) == 576
    assert ch.receive(1.0) == b""


def test_channel_outage_loses_everything_sent_during_it():
    ch = Channel(ChannelConfig(), np.random.default_rng(0), outages=[(0.0, 1.0)])
    ch.write(b"x" * 100, 0.1)
    assert ch.receive(2.0) == b"" and ch.bytes_lost == 100
    ch.write(b"y" * 10, 1.5)
    assert ch.receive(2.0) == b"y" * 10


def test_channel_corruption_flips_bits():
    ch = Channel(ChannelConfig(bit_error=0.5), np.random.default_rng(1))
    ch.write(bytes(1000), 0.0)
    data = ch.receive(1.0)
    assert len(data) == 1000 and ch.bytes_corrupted == sum(1 for b in data if b)


# ---------------------------------------------------------------- whole missions

def _run(name: str, **kw) -> dict:
    sim = Simulation(load_scenario(name), SimOptions(**kw))
    sim.run()
    return build_report(sim, 1.0)


def test_figure_4_8_mission_finds_the_unknown_obstacle_and_arrives_without_contact():
    r = _run("seed-fig4-8-unknown-obstacle", seed=3)
    assert r["reached"] and r["collisions"] == 0
    assert r["obstacles_discovered"] == 1 and r["replans"] >= 1
    assert r["min_clearance_m"] > 0.0
    assert r["mission_time_s"] < 156.0   # the seed's rover took 2 min 36 s
    assert r["spl"] > 0.8


def test_out_and_back_second_trip_needs_no_replanning():
    r = _run("out-and-back", seed=2)
    assert r["reached"] and r["collisions"] == 0
    assert len(r["trips"]) == 2 and len(r["legs"]) == 4
    assert r["trips"][0]["replans"] >= 1           # the first trip learns the two unknown boxes
    assert r["trips"][1]["replans"] == 0           # the second uses what was learned
    assert r["obstacles_discovered"] == 2


def test_the_seed_strategy_is_slower_than_ours_in_the_same_world():
    ours = _run("seed-fig4-8-unknown-obstacle", seed=1)
    seed = _run("seed-fig4-8-unknown-obstacle", seed=1, strategy="seed")
    assert ours["reached"] and seed["reached"] and seed["collisions"] == 0
    assert seed["mission_time_s"] > 1.5 * ours["mission_time_s"]


def test_rovernav_sim_writes_report_video_and_picture(tmp_path):
    out = tmp_path / "run"
    result = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "seed-large-obstacles", "--out", str(out),
                             "--seed", "2", "--quiet"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads((out / "report.json").read_text())
    for key in ("scenario", "strategy", "reached", "collisions", "mission_time_s", "wall_time_s", "path_length_m",
                "optimal_length_m", "spl", "min_clearance_m", "replans", "obstacles_discovered", "trips", "link"):
        assert key in report, key
    assert report["reached"] and report["collisions"] == 0
    assert (out / "summary.png").stat().st_size > 10_000
    import cv2
    video = cv2.VideoCapture(str(out / "video.mp4"))
    assert video.isOpened() and video.get(cv2.CAP_PROP_FRAME_COUNT) > 100


def test_rovernav_sim_refuses_an_unknown_scenario_and_a_bad_fault_window(tmp_path):
    r = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "no-such-arena", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "no scenario named 'no-such-arena'" in r.stderr
    r = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "--link-outage", "ten"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "START:DURATION" in r.stderr


def test_with_the_hosts_replanning_off_the_rover_gets_round_the_figure_4_8_obstacle_itself():
    r = _run("seed-fig4-8-unknown-obstacle", seed=1, host_replan=False)
    assert r["reached"] and r["collisions"] == 0 and r["replans"] == 0
    assert any("rover: replanned" in e["text"] for e in r["events"])   # the rover's own detour


def test_a_ten_second_camera_outage_mid_path_is_ridden_out_on_dead_reckoning():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(camera_outages=[(12.0, 10.0)]))
    assert r["reached"] and r["collisions"] == 0
    f = r["faults"]
    assert f["camera_lost_events"] == 1 and f["holds"] == []
    assert f["max_dr_error_m"] is not None and f["max_dr_error_m"] < 0.05


def test_a_firmware_reset_mid_mission_is_brought_back_up_to_date_and_the_mission_completes():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(firmware_resets=[15.0]))
    assert r["reached"] and r["collisions"] == 0 and len(r["legs"]) == 1
    assert any("rover restarted" in e["text"] for e in r["events"])


def test_a_dead_gyro_ends_the_mission_with_the_rovers_fault_not_a_hang():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(gyro_dies_at=15.0))
    assert not r["reached"] and r["error"] == "rover fault: gyro_silent"
    assert r["mission_time_s"] < 16.0 and r["faults"]["rover_faults"][0]["fault"] == "gyro_silent"


def test_a_host_restart_mid_mission_takes_up_the_same_leg_and_the_mission_completes():
    from rovernav.sim.runner import Faults

    r = _run("out-and-back", seed=1, faults=Faults(host_restarts=[80.0]))
    assert r["reached"] and r["collisions"] == 0 and len(r["legs"]) == 4
    assert any("host restarted" in e["text"] for e in r["events"])


def test_a_radio_outage_over_the_moment_the_obstacle_is_found_still_ends_without_contact():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(link_outages=[(8.0, 10.0)]))
    assert r["reached"] and r["collisions"] == 0
    assert r["faults"]["local_detours"] >= 0 and r["faults"]["max_dr_error_m"] < 0.05


def test_an_outage_too_long_to_trust_ends_in_a_safe_stop_and_a_resume():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(link_outages=[(8.0, 40.0)]))
    assert r["reached"] and r["collisions"] == 0
    f = r["faults"]
    assert len(f["holds"]) == 1 and f["holds"][0]["uncertainty_2sd_m"] <= 0.05
    assert f["hold_recovery_s"][0] is not None and f["holds"][0]["t_s"] + f["hold_recovery_s"][0] >= 48.0


def test_the_pose_law_drive_mode_completes_a_mission_and_the_report_says_so():
    ours = _run("seed-fig4-8-unknown-obstacle", seed=1, drive_mode="pose_law")
    assert ours["reached"] and ours["collisions"] == 0 and ours["drive_mode"] == "pose_law"


def test_rovernav_sim_compares_the_drive_modes(tmp_path):
    r = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "seed-large-obstacles", "--drive-mode", "both",
                        "--no-video", "--quiet", "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "faster: rovernav / " in r.stdout
    both = json.loads((tmp_path / "comparison.json").read_text())
    assert {x["drive_mode"] for x in both} == {"rotate_drive", "pose_law"}


# ---------------------------------------------------------------- contact ends the run

def test_the_world_names_what_the_rover_touches():
    w = World(2.0, 2.0, [Box(1.0, 1.0, 0.2, 0.2, known=False)])
    assert w.touching(1.0, 0.8, 0.0).startswith("obstacle 1 (unknown box at (1.00, 1.00) m")
    assert w.touching(0.05, 1.5, 0.0) == "the left wall"


def test_a_blind_rover_crashes_into_the_unknown_obstacle_and_the_run_ends_at_its_face(monkeypatch):
    # With its sonar deaf the rover cannot see Figure 4.8's obstacle: the run must end at the
    # obstacle's face (a crash), never pass through it, and say so.
    monkeypatch.setattr("rovernav.sim.plant.RoverPlant.sonar_mm", lambda self, world: 0)
    sim = Simulation(load_scenario("seed-fig4-8-unknown-obstacle"), SimOptions(seed=1, host_replan=False))
    box = next(b for b in sim.world.boxes if not b.known)
    deepest = -math.inf
    step = sim._rover

    def watched(now):
        nonlocal deepest
        step(now)
        x0, y0, x1, y1 = box.bounds
        p = sim.plant
        deepest = max(deepest, min(p.x - x0, x1 - p.x, p.y - y0, y1 - p.y))   # > 0: the centre is inside
    monkeypatch.setattr(sim, "_rover", watched)
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "crashed" and r["crashed"] and not r["reached"] and r["collisions"] == 1
    assert r["crash"]["against"].startswith("obstacle 1 (unknown box")
    assert r["mission_time_s"] == pytest.approx(r["crash"]["t_s"], abs=0.05)
    assert deepest < 0.0   # the rover's centre never entered the box
    json.dumps(r, allow_nan=False)


def test_a_target_two_centimetres_from_the_start_is_reached_at_once():
    from rovernav.scenario import parse_scenario

    sc = parse_scenario("version = 1\n[arena]\nwidth_m = 2.0\nheight_m = 1.5\n[start]\nx_m = 0.5\ny_m = 0.5\n"
                        "[target]\nx_m = 0.52\ny_m = 0.5\n")
    sim = Simulation(sc, SimOptions(seed=1, max_time_s=120))
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "reached" and r["mission_time_s"] < 5.0 and not r["timed_out"]
