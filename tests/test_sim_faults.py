"""Whole simulated missions under faults: camera and radio outages, a firmware reset, a dead
gyro, host restarts, an attacker on the radio, and a lossy line. Each either completes without
contact or ends in the verdict it should, never a hang. (Split from test_sim.py.)"""

from __future__ import annotations

import json

import pytest
from tests.sim_runs import rover_events as _rover_events
from tests.sim_runs import run_report as _run
from tests.sim_runs import simulate_named as _simulate

from rovernav.evaluation.report import build_report
from rovernav.link import messages_gen as mg
from rovernav.mission import Failure
from rovernav.scenario import load_scenario
from rovernav.sim.runner import HOST_BOOT_ID, SimOptions, Simulation


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
    assert _rover_events(sim, mg.EventKind.BOOT) == 2  # booted, and booted again after the reset


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
    assert sim.restarts_done == 1 and sim.mission.host_boot_id == HOST_BOOT_ID + 1  # a new host finished it


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
    assert r["faults"]["max_dr_error_m"] < 0.05  # dead reckoning through the outage


@pytest.mark.mission
def test_an_outage_too_long_to_trust_ends_in_a_safe_stop_and_a_resume():
    from rovernav.sim.runner import Faults

    r = _run("seed-fig4-8-unknown-obstacle", seed=1, faults=Faults(link_outages=[(8.0, 40.0)]))
    assert r["reached"] and r["collisions"] == 0
    f = r["faults"]
    assert len(f["holds"]) == 1 and f["holds"][0]["uncertainty_2sd_m"] <= 0.05
    assert f["hold_recovery_s"][0] is not None and f["holds"][0]["t_s"] + f["hold_recovery_s"][0] >= 48.0


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
    sim = Simulation(
        load_scenario("seed-fig4-8-unknown-obstacle"), SimOptions(seed=1, attacker=True, signed=False, max_time_s=90.0)
    )
    sim.run()
    r = build_report(sim, 1.0)
    assert not r["reached"]
    assert _rover_events(sim, mg.EventKind.STOPPED) >= 10
    assert r["link"]["signing"]["rover_refused"]["unverified"] == r["link"]["signing"]["attacker"]["injected"]["forged"]


@pytest.mark.mission
def test_a_mission_at_one_percent_byte_loss_reaches_its_target():
    # 1 % of bytes lost and 0.1 % with a flipped bit, both ways: about two in five signed PATH
    # chunks, and one FIX in four, do not arrive. Every exchange is retried (protocol/README.md).
    from rovernav.radio import ChannelConfig

    clean, _ = _simulate("seed-fig4-8-unknown-obstacle", seed=2)
    r, sim = _simulate("seed-fig4-8-unknown-obstacle", seed=2, channel=ChannelConfig(byte_loss=0.01, bit_error=0.001))
    assert r["reached"] and r["collisions"] == 0
    assert r["mission_time_s"] < 1.3 * clean["mission_time_s"]
    link = r["link"]["quality"]  # report.json's, as the host measured it
    assert link == json.loads(json.dumps(sim.mission.link_summary()))
    assert 0.5 < link["host_to_rover"]["success"] < 0.95 and 0.5 < link["rover_to_host"]["success"] < 0.95
    assert sum(link["host_sent_again"].values()) > 0
    assert sim.mission.finished and sim.core.probe().state in (mg.RoverState.ARRIVED, mg.RoverState.IDLE)
