"""benchmarks/fleet_shuttle.py's seeds and its rates over the fleet's runs (--fleet-only), on
made-up runs."""

from __future__ import annotations

from types import SimpleNamespace

import pytest


def test_seeds_are_lists_and_ranges_and_anything_else_is_one_line(benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    assert bench.parse_seeds("1,2,3") == [1, 2, 3]
    assert bench.parse_seeds("1-5,8") == [1, 2, 3, 4, 5, 8]
    assert bench.parse_seeds(" 7 ") == [7]
    for bad, says in (("3-1", "backwards"), ("x", "neither"), ("1-", "neither"), (",", "no seed")):
        with pytest.raises(ValueError, match=says):
            bench.parse_seeds(bad)
    assert set(bench.RADIOS) >= {"clean", "loss1", "burst2", "loss5"}  # the lossy-radio benchmark's radios


def _row(seed, done, outcome="reached", contacts=0, crash=None):
    return {
        "seed": seed,
        "outcome": outcome,
        "trips_done": done,
        "trips_asked": 15,
        "time_s": 1000.0 + seed,
        "contacts": contacts,
        "holds": 3,
        "crash": crash,
        "stuck": outcome == "stuck",
        "errors": [],
    }


def test_the_fleets_rates_count_whole_stuck_and_crashed_runs(capsys, benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    a = SimpleNamespace(trips=5, radio="clean")
    crash = {"rover": 2, "against": "rover 3", "t_s": 99.0}
    rows = [_row(2, 15), _row(1, 15), _row(3, 6, "stuck"), _row(4, 2, "crashed", 1, crash)]
    assert bench.fleet_rates(rows, a) is False
    out = capsys.readouterr().out
    assert "fleet runs whole 2/4, stuck 1, crashed 1, other 0" in out
    assert "median time of the whole runs 1002 s" in out and "trips done 38/60" in out
    assert "rover 2 against rover 3 at 99.0 s" in out
    lines = [line for line in out.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert [line.split("|")[1].strip() for line in lines] == ["1", "2", "3", "4"]  # by seed
    assert bench.fleet_rates([_row(1, 15)], a) is True
