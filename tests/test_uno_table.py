"""benchmarks/uno_table.py's table and failures, from made-up run reports (no simulator runs).

Its table once said "N/M reached, 0 collisions" whatever the runs did: on BARN-style worlds the
progress lines said "NOT reached, 1 collisions" for runs the table showed with 0.
"""

from __future__ import annotations

import pytest

SCENARIO = "seed-fig4-8-unknown-obstacle"


def _timing(worst_us: float = 3000.0, jitter_us: float = 200.0, margin_bytes: int = 300) -> dict:
    return {
        "worst_step": {"us": worst_us, "state": "drive", "flags": ["fix"]},
        "period_jitter": {"max_abs_us": jitter_us},
        "stack": {"used_bytes": 500, "margin_bytes": margin_bytes},
        "step_time": {"median_us": 1200.0, "p99_us": 2500.0},
    }


def _run(reached: bool, collisions: int, mission_time_s: float, **timing) -> dict:
    return {
        "reached": reached,
        "collisions": collisions,
        "mission_time_s": mission_time_s,
        "uno_timing": _timing(**timing),
    }


@pytest.fixture
def uno_table(benchmark_module):
    return benchmark_module("uno_table")


def test_a_run_with_collisions_is_shown_with_them(uno_table):
    native = [_run(True, 0, 40.0), _run(False, 1, 1500.0), _run(True, 2, 44.0)]
    uno = [_run(True, 0, 41.0), _run(False, 1, 1500.0), _run(True, 2, 46.0)]
    assert uno_table.outcome(native[1]) == "NOT reached, 1 collisions, 1500.0 s"
    assert uno_table.runs_cell(native) == "2/3 reached, 3 collisions, 42.0 s"
    row = uno_table.table_row(SCENARIO, native, uno)
    assert row.startswith(
        f"| {SCENARIO} | 2/3 reached, 3 collisions, 42.0 s | 2/3 reached, 3 collisions, 43.5 s (+3.6 %) | "
    )
    text, failures = uno_table.table(
        [SCENARIO],
        [1, 2, 3],
        {
            (SCENARIO, rover, seed): r
            for rover, runs in (("native", native), ("uno", uno))
            for seed, r in zip((1, 2, 3), runs)
        },
    )
    assert text.splitlines()[2] == row and "0 collisions" not in row
    assert failures == []  # the same outcomes both ways, every figure within its limit


def test_runs_that_all_fail_have_no_time_and_every_collision(uno_table):
    assert uno_table.runs_cell([_run(False, 1, 1500.0), _run(False, 4, 12.5)]) == "0/2 reached, 5 collisions, no time"


def test_outcomes_that_differ_and_figures_past_their_limits_fail_naming_them(uno_table):
    native = [_run(True, 0, 40.0)]
    uno = [_run(True, 1, 40.0, worst_us=5200.0, jitter_us=1500.0, margin_bytes=200)]
    assert uno_table.failures_of(SCENARIO, [7], native, uno) == [
        f"{SCENARIO} seed 7: outcomes differ (native reached, 0 collisions, 40.0 s; "
        "Uno image reached, 1 collisions, 40.0 s)",
        f"{SCENARIO}: worst step 5.20 ms > 5 ms",
        f"{SCENARIO}: jitter 1.50 ms > 1 ms",
        f"{SCENARIO}: stack margin 200 B < 256 B",
    ]
