"""A test helper: whole simulated missions on a shared scenario, by name, and what they report.
Used by the mission tests (test_sim_missions.py) and the fault tests (test_sim_faults.py)."""

from __future__ import annotations

from rovernav.evaluation.report import build_report
from rovernav.scenario import load_scenario
from rovernav.sim.runner import SimOptions, Simulation


def run_report(name: str, **kw) -> dict:
    return simulate_named(name, **kw)[0]


def simulate_named(name: str, **kw) -> tuple[dict, Simulation]:
    """The report of a run, and the run itself (its mission's failure kind, the rover's events)."""
    sim = Simulation(load_scenario(name), SimOptions(**kw))
    sim.run()
    return build_report(sim, 1.0), sim


def rover_events(sim, kind) -> int:
    """How many EVENT frames of `kind` the host took from the rover."""
    return sum(1 for _t, e in sim.mission.events if e.kind == kind)
