"""benchmarks/time_by_state.py's split of the sweeps by what began them, on made-up samples."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import SimpleNamespace

from rovernav.link import messages_gen as mg

ROOT = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("time_by_state", ROOT / "benchmarks" / "time_by_state.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _samples(states: list[tuple[float, mg.RoverState]]) -> list[SimpleNamespace]:
    return [SimpleNamespace(t_s=t, state=s) for t, s in states]


def test_each_sweep_is_put_down_to_what_began_it():
    S = mg.RoverState
    samples = _samples(
        [
            (0.00, S.IDLE),
            (0.01, S.SCAN),
            (1.50, S.ROTATE),  # the start: other
            (2.00, S.DRIVE),
            (5.00, S.SCAN),
            (6.50, S.DRIVE),  # from DRIVE, no event: every 0.3 m
            (8.00, S.SCAN),
            (9.40, S.ROTATE),  # a REFLEX event at 8.00 s
            (9.50, S.DRIVE),
            (12.00, S.SCAN),
            (13.45, S.ROTATE),  # a WAYPOINT_REACHED at 12.00 s
            (14.00, S.ARRIVED),
        ]
    )
    events = [
        SimpleNamespace(kind=mg.EventKind.REFLEX, time_ms=8000),
        SimpleNamespace(kind=mg.EventKind.WAYPOINT_REACHED, time_ms=12000),
        SimpleNamespace(kind=mg.EventKind.WAYPOINT_REACHED, time_ms=3000),
    ]  # no sweep then
    causes = _module().sweep_causes(samples, events)
    assert causes == {"other": [1.49], "every 0.3 m": [1.5], "reflex": [1.4], "before a turn": [1.45]}


def test_a_sweep_still_running_at_the_end_counts_to_the_last_sample():
    S = mg.RoverState
    causes = _module().sweep_causes(_samples([(0.0, S.DRIVE), (1.0, S.SCAN), (1.7, S.SCAN)]), [])
    assert causes == {"every 0.3 m": [0.7]}
