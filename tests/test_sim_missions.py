"""The simulator: plant, sensors, world geometry, radio, and whole missions on the shared scenarios."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from rovernav.link import messages_gen as mg
from rovernav.mission import Failure
from rovernav.scenario import load_scenario
from rovernav.sim.report import build_report
from rovernav.sim.runner import HOST_BOOT_ID, SimOptions, Simulation


# ---------------------------------------------------------------- whole missions

def _run(name: str, **kw) -> dict:
    return _simulate(name, **kw)[0]


def _simulate(name: str, **kw) -> tuple[dict, Simulation]:
    """The report of a run, and the run itself (its mission's failure kind, the rover's events)."""
    sim = Simulation(load_scenario(name), SimOptions(**kw))
    sim.run()
    return build_report(sim, 1.0), sim


def _rover_events(sim, kind) -> int:
    """How many EVENT frames of `kind` the host took from the rover."""
    return sum(1 for _t, e in sim.mission.events if e.kind == kind)


@pytest.mark.mission
def test_figure_4_8_mission_finds_the_unknown_obstacle_and_arrives_without_contact():
    r = _run("seed-fig4-8-unknown-obstacle", seed=3)
    assert r["reached"] and r["collisions"] == 0
    assert r["obstacles_discovered"] == 1 and r["replans"] >= 1
    assert r["min_clearance_m"] > 0.0
    assert r["mission_time_s"] < 156.0   # the seed's rover took 2 min 36 s
    assert r["spl"] > 0.8


@pytest.mark.mission
def test_out_and_back_second_trip_needs_no_replanning():
    r = _run("out-and-back", seed=2)
    assert r["reached"] and r["collisions"] == 0
    assert len(r["trips"]) == 2 and len(r["legs"]) == 4
    assert r["trips"][0]["replans"] >= 1           # the first trip learns the two unknown boxes
    assert r["trips"][1]["replans"] == 0           # the second uses what was learned
    assert r["obstacles_discovered"] == 2


@pytest.mark.mission
def test_the_seed_strategy_is_slower_than_ours_in_the_same_world():
    ours = _run("seed-fig4-8-unknown-obstacle", seed=1)
    seed = _run("seed-fig4-8-unknown-obstacle", seed=1, strategy="seed")
    assert ours["reached"] and seed["reached"] and seed["collisions"] == 0
    assert seed["mission_time_s"] > 1.5 * ours["mission_time_s"]


@pytest.mark.mission
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


@pytest.mark.mission
def test_with_the_hosts_replanning_off_the_rover_gets_round_the_figure_4_8_obstacle_itself():
    r, sim = _simulate("seed-fig4-8-unknown-obstacle", seed=1, host_replan=False)
    assert r["reached"] and r["collisions"] == 0 and r["replans"] == 0
    assert _rover_events(sim, mg.EventKind.REPLANNED) >= 1   # the rover's own detour


@pytest.mark.mission
def test_an_eight_second_camera_outage_mid_path_is_ridden_out_on_dead_reckoning():
    from rovernav.sim.runner import Faults

    # Eight seconds of driving stays inside the uncertainty the rover accepts; ten seconds of
    # it (the rover sweeps less of the time than it did) reaches the limit and holds still.
    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(camera_outages=[(12.0, 8.0)]))
    assert r["reached"] and r["collisions"] == 0
    f = r["faults"]
    assert f["camera_lost_events"] == 1 and f["holds"] == []
    assert f["max_dr_error_m"] is not None and f["max_dr_error_m"] < 0.05


@pytest.mark.mission
def test_a_firmware_reset_mid_mission_is_brought_back_up_to_date_and_the_mission_completes():
    from rovernav.sim.runner import Faults

    r, sim = _simulate("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(firmware_resets=[15.0]))
    assert r["reached"] and r["collisions"] == 0 and len(r["legs"]) == 1
    assert _rover_events(sim, mg.EventKind.BOOT) == 2   # booted, and booted again after the reset


@pytest.mark.mission
def test_a_dead_gyro_ends_the_mission_with_the_rovers_fault_not_a_hang():
    from rovernav.sim.runner import Faults

    r, sim = _simulate("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(gyro_dies_at=15.0))
    assert not r["reached"] and sim.mission.failure is Failure.ROVER_FAULT and r["failure"] == "rover_fault"
    assert r["mission_time_s"] < 16.0 and r["faults"]["rover_faults"][0]["fault"] == "gyro_silent"


@pytest.mark.mission
def test_a_host_restart_mid_mission_takes_up_the_same_leg_and_the_mission_completes():
    from rovernav.sim.runner import Faults

    r, sim = _simulate("out-and-back", seed=1, faults=Faults(host_restarts=[80.0]))
    assert r["reached"] and r["collisions"] == 0 and len(r["legs"]) == 4
    assert sim.restarts_done == 1 and sim.mission.host_boot_id == HOST_BOOT_ID + 1   # a new host finished it


@pytest.mark.mission
def test_a_host_restarted_on_the_first_leg_gets_its_path_taken():
    # Found replaying logs of generated arenas with random faults: the new host's first path had
    # the id and size of the one the rover held from the old host, so the rover took it for a
    # repeat, ACKed it and never said PATH_ACCEPTED; the mission failed 30 s later.
    from rovernav.evaluation.arenas import generate_arenas
    from rovernav.sim.runner import Faults

    arena = next(a for a in generate_arenas(24, seed=1) if a.scenario.name.startswith("arena-0023"))
    sim = Simulation(arena.scenario, SimOptions(seed=832968, faults=Faults(host_restarts=[9.5]), max_time_s=300))
    sim.run()
    assert sim.outcome == "reached" and sim.restarts_done == 1


@pytest.mark.mission
def test_a_radio_outage_beside_an_unknown_box_ends_without_contact():
    # An outage trial that once ended against the Figure 4.8 box's corner: the rover's sweep
    # beside the box was lost on the radio, so the host's map never had the corner. The rover
    # now sweeps again when the radio comes back, before it moves on.
    from rovernav.sim.runner import Faults

    seed, start_s, duration_s = 2151, 10.3, 14.8

    r = _run("seed-fig4-8-unknown-obstacle", seed=seed, faults=Faults(link_outages=[(start_s, duration_s)]))
    assert r["reached"] and r["collisions"] == 0 and not r["crashed"]


@pytest.mark.mission
def test_a_radio_outage_over_the_moment_the_obstacle_is_found_still_ends_without_contact():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(link_outages=[(8.0, 10.0)]))
    assert r["reached"] and r["collisions"] == 0
    assert r["faults"]["max_dr_error_m"] < 0.05   # dead reckoning through the outage


@pytest.mark.mission
def test_an_outage_too_long_to_trust_ends_in_a_safe_stop_and_a_resume():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(link_outages=[(8.0, 40.0)]))
    assert r["reached"] and r["collisions"] == 0
    f = r["faults"]
    assert len(f["holds"]) == 1 and f["holds"][0]["uncertainty_2sd_m"] <= 0.05
    assert f["hold_recovery_s"][0] is not None and f["holds"][0]["t_s"] + f["hold_recovery_s"][0] >= 48.0


@pytest.mark.mission
def test_the_pose_law_drive_mode_completes_a_mission_and_the_report_says_so():
    ours = _run("seed-fig4-8-unknown-obstacle", seed=1, drive_mode="pose_law")
    assert ours["reached"] and ours["collisions"] == 0 and ours["drive_mode"] == "pose_law"


@pytest.mark.mission
def test_rovernav_sim_compares_the_drive_modes(tmp_path):
    r = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "seed-large-obstacles", "--drive-mode", "both",
                        "--no-video", "--quiet", "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "faster: rovernav / " in r.stdout
    both = json.loads((tmp_path / "comparison.json").read_text())
    assert {x["drive_mode"] for x in both} == {"rotate_drive", "pose_law"}


# ---------------------------------------------------------------- contact ends the run


@pytest.mark.mission
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


@pytest.mark.mission
def test_a_target_two_centimetres_from_the_start_is_reached_at_once():
    from rovernav.scenario import parse_scenario

    sc = parse_scenario("version = 1\n[arena]\nwidth_m = 2.0\nheight_m = 1.5\n[start]\nx_m = 0.5\ny_m = 0.5\n"
                        "[target]\nx_m = 0.52\ny_m = 0.5\n")
    sim = Simulation(sc, SimOptions(seed=1, max_time_s=120))
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "reached" and r["mission_time_s"] < 5.0 and not r["timed_out"]


# ---------------------------------------------------------------- walls and posts

WALL_AND_POST = """
name = "wall-with-a-gap-and-a-post"
version = 1
[arena]
width_m = 2.36
height_m = 1.75
[start]
x_m = 0.3
y_m = 0.6
heading_deg = 90.0
[target]
x_m = 2.05
y_m = 0.6
[[walls]]   # across the straight way, a gap of 0.45 m above it
x0_m = 1.2
y0_m = 0.0
x1_m = 1.2
y1_m = 1.05
thickness_m = 0.05
known = false
[[walls]]
x0_m = 1.2
y0_m = 1.5
x1_m = 1.2
y1_m = 1.75
thickness_m = 0.05
known = false
[[posts]]   # beyond the gap, on the way down to the target
x_m = 1.62
y_m = 1.0
radius_m = 0.04
known = false
"""


@pytest.mark.mission
def test_a_mission_past_an_unknown_wall_with_a_gap_and_an_unknown_post_arrives(tmp_path):
    from rovernav.scenario import parse_scenario
    from rovernav.arena_picture import Canvas, draw_arena

    sim = Simulation(parse_scenario(WALL_AND_POST), SimOptions(seed=1, max_time_s=300))
    assert len(sim.world.walls) == 2 and len(sim.world.posts) == 1
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "reached" and r["collisions"] == 0 and r["min_clearance_m"] > 0.0, r["events"]
    assert r["obstacles_unknown"] == 3 and r["obstacles_discovered"] >= 2 and r["replans"] >= 1
    # the summary picture draws the unknown walls and the post hatched like unknown boxes
    canvas = Canvas(sim.scenario.arena.width_m, sim.scenario.arena.height_m)
    draw_arena(canvas, sim)
    for x, y in ((1.2, 0.3), (1.2, 1.6), (1.62, 1.0)):
        u, v = canvas.pt(x, y)
        patch = canvas.img[v - 3:v + 4, u - 3:u + 4].reshape(-1, 3).tolist()
        assert [150, 150, 200] in patch or [90, 90, 160] in patch, (x, y)


@pytest.mark.mission
def test_a_blind_rover_crashes_into_an_unknown_wall_and_the_report_names_it(monkeypatch):
    from rovernav.scenario import parse_scenario

    monkeypatch.setattr("rovernav.sim.plant.RoverPlant.sonar_mm", lambda self, world: 0)
    sim = Simulation(parse_scenario(WALL_AND_POST), SimOptions(seed=1, host_replan=False, max_time_s=120))
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "crashed"
    assert r["crash"]["against"].startswith("wall 1 (unknown, from (1.20, 0.00) to (1.20, 1.05) m")
    assert r["crash"]["x_m"] < 1.2


# ---------------------------------------------------------------- the unreachable verdict

_WALL_ACROSS = """version = 1
[arena]
width_m = 2.36
height_m = 1.75
[start]
x_m = 0.4
y_m = 0.875
heading_deg = 90.0
[target]
x_m = 2.0
y_m = 0.875
"""


def _unknown_wall(y0: float, y1: float) -> str:
    return (f"[[walls]]\nx0_m = 1.2\ny0_m = {y0}\nx1_m = 1.2\ny1_m = {y1}\nthickness_m = 0.04\nknown = false\n")


@pytest.mark.mission
def test_a_gap_one_cell_wider_than_the_rover_needs_is_found_and_driven_through():
    from rovernav.planning import PlannerConfig
    from rovernav.scenario import parse_scenario

    gap = 2 * PlannerConfig().inflation_m + PlannerConfig().resolution_m   # 0.37 m
    lower_top = 0.875 - gap / 2
    text = _WALL_ACROSS + _unknown_wall(0.0, round(lower_top, 3)) + _unknown_wall(round(lower_top + gap, 3), 1.75)
    sim = Simulation(parse_scenario(text), SimOptions(seed=1, max_time_s=300))
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "reached" and r["collisions"] == 0


@pytest.mark.mission
def test_a_target_an_unknown_wall_encloses_gets_the_no_path_verdict_after_the_rover_has_looked():
    from rovernav.scenario import parse_scenario

    sim = Simulation(parse_scenario(_WALL_ACROSS + _unknown_wall(0.0, 1.75)), SimOptions(seed=1, max_time_s=300))
    sim.run()
    r = build_report(sim, 1.0)
    assert r["outcome"] == "no_path" and r["collisions"] == 0 and not r["timed_out"]
    assert r["obstacles_discovered"] == 1 and r["replans"] >= 1   # the verdict came from what the sonar saw


@pytest.mark.mission
def test_an_attacker_on_the_radio_is_refused_frame_by_frame_and_the_mission_goes_on():
    r = _run("seed-fig4-8-unknown-obstacle", seed=1, attacker=True)
    assert r["reached"] and r["collisions"] == 0
    s = r["link"]["signing"]
    a = s["attacker"]
    assert s["signed"] and a["injected_total"] >= 40 and min(a["injected"].values()) >= 10
    assert a["refused_total"] == a["injected_total"]
    assert {k: v for k, v in s["rover_refused"].items() if v} == a["expected_refusals"]
    assert s["host_refused"] == {"bad_tag": 0, "replayed": 0, "not_signed": 0, "unverified": 0}


@pytest.mark.mission
def test_on_an_unsigned_link_the_same_attacker_stops_the_rover():
    # Why the link is signed: without a key the rover obeys the injected STOPs and replays.
    sim = Simulation(load_scenario("seed-fig4-8-unknown-obstacle"),
                     SimOptions(seed=1, attacker=True, signed=False, max_time_s=90.0))
    sim.run()
    r = build_report(sim, 1.0)
    assert not r["reached"]
    assert _rover_events(sim, mg.EventKind.STOPPED) >= 10
    assert r["link"]["signing"]["rover_refused"]["unverified"] == r["link"]["signing"]["attacker"]["injected"]["forged"]


@pytest.mark.mission
def test_a_mission_at_one_percent_byte_loss_reaches_its_target():
    # 1 % of bytes lost and 0.1 % with a flipped bit, both ways: about two in five signed PATH
    # chunks, and one FIX in four, do not arrive. Every exchange is retried (protocol/README.md).
    from rovernav.sim.channel import ChannelConfig

    clean, _ = _simulate("seed-fig4-8-unknown-obstacle", seed=2)
    r, sim = _simulate("seed-fig4-8-unknown-obstacle", seed=2, channel=ChannelConfig(byte_loss=0.01, bit_error=0.001))
    assert r["reached"] and r["collisions"] == 0
    assert r["mission_time_s"] < 1.3 * clean["mission_time_s"]
    link = r["link"]["quality"]   # report.json's, as the host measured it
    assert link == json.loads(json.dumps(sim.mission.link_summary()))
    assert 0.5 < link["host_to_rover"]["success"] < 0.95 and 0.5 < link["rover_to_host"]["success"] < 0.95
    assert sum(link["host_sent_again"].values()) > 0
    assert sim.mission.finished and sim.core.probe().state in (mg.RoverState.ARRIVED, mg.RoverState.IDLE)


def test_cellular_arena_38_where_a_rover_backed_out_into_what_it_never_saw_is_reached():
    # Cellular arena 38 of seed 2611 (rovernav arenas --seed 2611 --family cellular): the rover
    # drove east, turned on the spot to 153 degrees, swept, and had no room for the next turn.
    # It used to back straight out along 333 degrees, over ground no part of it had been on, into
    # an unseen box (crashed at 63.5 s). It now turns back onto its track first; since the look
    # after a sharp turn (issue 26) its way through this arena no longer backs out there, and the
    # rule itself is tested natively ("a rover that has turned since it drove turns back onto its
    # track before it backs out along it", test_motion.cpp). The arena stays as a regression.
    from rovernav.evaluation.arenas import generate_arena

    sim = Simulation(generate_arena(2611, 38, "cellular").scenario, SimOptions(seed=1, max_time_s=400))
    sim.run()
    assert sim.outcome == "reached" and sim.collisions == 0
