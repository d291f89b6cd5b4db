"""`rovernav trials`: the scores and the headline figures on hand-made rows, the gate, the arena
sample, bad input, the hang and error guards, and whole benchmarks on two tiny arenas (marked
`mission`: serial, and on a one-worker local dask cluster)."""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest

from rovernav.cli import main
from rovernav.evaluation.trials import (
    TrialJob,
    barn_score,
    gate_violations,
    headline,
    headlines_by,
    row_from_report,
    run_jobs,
    run_trial,
    sample_arenas,
    time_score,
)

EASY = """\
version = 1
[arena]
width_m = 1.4
height_m = 1.0
[start]
x_m = 0.4
y_m = 0.4
[target]
x_m = 0.9
y_m = 0.4
"""

# The target stands in a closed box of known walls: no path exists, as its [generated] label says.
ENCLOSED = """\
version = 1
[arena]
width_m = 1.4
height_m = 1.0
[start]
x_m = 0.3
y_m = 0.5
[target]
x_m = 1.0
y_m = 0.5
[[obstacles]]
x_m = 1.0
y_m = 0.75
w_m = 0.5
h_m = 0.1
[[obstacles]]
x_m = 1.0
y_m = 0.25
w_m = 0.5
h_m = 0.1
[[obstacles]]
x_m = 0.75
y_m = 0.5
w_m = 0.1
h_m = 0.4
[[obstacles]]
x_m = 1.25
y_m = 0.5
w_m = 0.1
h_m = 0.4
[generated]
family = "enclosure"
seed = 0
index = 1
solvable = false
[generated.difficulty]
closest_obstacle_m = 0.2
mean_clearance_m = 0.3
dispersion = 0.1
characteristic_dimension_m = 0.4
narrowest_dimension_m = 0.3
score = 0.9
band = "hard"
"""


def _meta(family="wall_gap", band="easy", score=0.2, solvable=True) -> dict:
    return {"family": family, "solvable": solvable, "difficulty": {"score": score, "band": band}}


def _report(**kw) -> dict:
    """The fields of build_report's dict that a row reads: a reached, contact-free 20 s run, OT 10 s,
    on a solvable, labelled arena."""
    return {
        "strategy": "rovernav",
        "seed": 1,
        "scenario_meta": _meta(),
        "outcome": "reached",
        "reached": True,
        "collisions": 0,
        "crashed": False,
        "crash": None,
        "timed_out": False,
        "mission_time_s": 20.0,
        "optimal_time_s": 10.0,
        "optimal_length_m": 1.0,
        "path_length_m": 1.1,
        "spl": 0.9,
        "min_clearance_m": 0.05,
        "replans": 0,
        "wall_time_s": 1.0,
        "error": None,
        "faults": {"max_dr_error_m": None},
    } | kw


def _row(meta=None, arena="arena-0000", **kw) -> dict:
    return row_from_report(_report(scenario_meta=_meta() if meta is None else meta, **kw), arena)


def _strict_json(path: Path):
    def refuse(constant):
        raise AssertionError(f"{path} is not strict JSON: {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


# ---------------------------------------------------------------- scores


@pytest.mark.parametrize(
    "success, ot, at, expected",
    [
        (True, 10.0, 20.0, 10.0 / 40.0),  # faster than 4 OT: clipped up to 4 OT, the best score, 0.25
        (True, 10.0, 60.0, 10.0 / 60.0),  # between 4 OT and 8 OT: OT / AT
        (True, 10.0, 200.0, 10.0 / 80.0),  # slower than 8 OT: clipped down to 8 OT, 0.125
        (False, 10.0, 20.0, 0.0),  # a failure scores 0
        (True, None, 20.0, None),  # no optimal time: undefined
    ],
)
def test_barn_score_is_success_times_optimal_time_over_actual_time_clipped_to_4_to_8_optimal_times(
    success, ot, at, expected
):
    assert barn_score(success, ot, at) == (pytest.approx(expected) if expected is not None else None)


@pytest.mark.parametrize(
    "success, ot, at, expected", [(True, 10.0, 5.0, 1.0), (True, 10.0, 20.0, 0.5), (False, 10.0, 20.0, 0.0)]
)
def test_time_score_is_optimal_time_over_actual_time_and_never_above_one(success, ot, at, expected):
    assert time_score(success, ot, at) == pytest.approx(expected)


def test_a_reached_run_is_a_success_only_without_any_contact():
    clean = _row()
    crashed = _row(crashed=True, crash={"t_s": 12.5, "x_m": 1, "y_m": 1, "heading_deg": 0, "against": "obstacle 2"})
    touched = _row(collisions=1)
    assert clean["success"] and not clean["failed"] and clean["reason"] is None
    assert clean["barn_score"] == pytest.approx(0.25) and clean["time_ratio"] == pytest.approx(2.0)
    for row in (crashed, touched):
        assert row["crashed"] and not row["success"] and row["failed"] and row["barn_score"] == 0.0
    assert crashed["crash_against"] == "obstacle 2" and "obstacle 2" in crashed["reason"]


def test_an_unreachable_verdict_is_false_on_a_solvable_arena_and_correct_on_an_unsolvable_one():
    said = {"outcome": "no_path", "reached": False, "mission_time_s": 0.5, "error": "no path to (1.00, 0.50) m"}
    false = _row(meta=_meta(solvable=True), **said)
    correct = _row(meta=_meta(solvable=False), optimal_length_m=None, optimal_time_s=None, **said)
    assert false["verdict_unreachable"] and false["false_unreachable"] and not false["correct_unreachable"]
    assert false["failed"] and false["reason"].startswith("false 'unreachable'")
    assert correct["verdict_unreachable"] and correct["correct_unreachable"] and not correct["false_unreachable"]
    assert not correct["failed"] and correct["barn_score"] is None
    # On an unsolvable arena anything but the verdict is a failure.
    timed_out = _row(meta=_meta(solvable=False), outcome="timeout", reached=False, timed_out=True, optimal_time_s=None)
    assert timed_out["failed"] and not timed_out["correct_unreachable"]


def test_an_unlabelled_arena_is_solvable_when_the_clairvoyant_planner_finds_a_path():
    assert _row(meta={})["solvable"] is True and _row(meta={})["family"] == "unlabelled"
    walled = row_from_report(
        _report(scenario_meta=None, outcome="no_path", reached=False, optimal_length_m=None, optimal_time_s=None),
        "arena-0001",
    )
    assert walled["solvable"] is False and walled["correct_unreachable"]


def test_headline_rates_count_successes_on_solvable_runs_and_verdicts_on_their_own_arenas():
    rows = [
        _row(mission_time_s=20.0),  # success, ratio 2, BARN 0.25
        _row(mission_time_s=60.0),  # success, ratio 6, BARN 1/6
        _row(crashed=True, reached=False, outcome="crashed"),  # crash on a solvable arena
        _row(outcome="no_path", reached=False),  # false 'unreachable'
        _row(meta=_meta(solvable=False), outcome="no_path", reached=False, optimal_time_s=None),  # correct
        _row(meta=_meta(solvable=False), outcome="timeout", reached=False, timed_out=True, optimal_time_s=None),
    ]
    h = headline(rows)
    assert (h["runs"], h["solvable_runs"], h["unsolvable_runs"]) == (6, 4, 2)
    assert h["success_rate"] == pytest.approx(2 / 4)
    assert h["crash_rate"] == pytest.approx(1 / 6)
    assert h["false_unreachable_rate"] == pytest.approx(1 / 4)
    assert h["correct_unreachable_rate"] == pytest.approx(1 / 2)
    assert (h["timeouts"], h["hung"], h["errors"], h["failed"]) == (1, 0, 0, 3)
    assert h["median_time_ratio"] == pytest.approx(4.0)  # over the two successes only
    assert h["mean_barn_score"] == pytest.approx((0.25 + 10 / 60 + 0 + 0) / 4, abs=1e-4)  # row scores: 4 digits
    assert headline([])["success_rate"] is None


def test_bands_are_ordered_by_difficulty_and_families_by_name_with_unlabelled_last():
    rows = [
        _row(meta=_meta("wall_gap", "hard", 0.9)),
        _row(meta=_meta("maze", "easy", 0.1)),
        _row(meta=_meta("maze", "medium", 0.5)),
        _row(meta={}),
    ]
    assert list(headlines_by(rows, "band")["rovernav"]) == ["easy", "medium", "hard", "unlabelled"]
    assert list(headlines_by(rows, "family")["rovernav"]) == ["maze", "wall_gap", "unlabelled"]


def test_the_gate_fails_on_the_rovernav_strategy_only_and_on_the_categories_asked():
    crash = dict(crashed=True, reached=False, outcome="crashed")
    rows = [
        _row(strategy="seed", **crash),
        _row(arena="a1", outcome="timeout", reached=False, timed_out=True),
        _row(arena="a2", outcome="hung", reached=False),
        _row(arena="a3", **crash),
    ]
    found = gate_violations(rows, ["crash", "timeout"])
    assert [(v["run"], v["category"]) for v in found] == [
        ("a1 rovernav s1", "timeout"),
        ("a2 rovernav s1", "timeout"),
        ("a3 rovernav s1", "crash"),
    ]
    assert gate_violations(rows, ["false_unreachable", "error"]) == []


def test_the_sample_of_unlabelled_arenas_is_evenly_spaced_through_the_sorted_names():
    arenas = [(Path(f"arena-{i:04d}.toml"), None) for i in range(10)]
    assert [p.stem for p, _ in sample_arenas(arenas, 4)] == ["arena-0000", "arena-0002", "arena-0005", "arena-0007"]
    assert sample_arenas(arenas, 1) == arenas[:1] and sample_arenas(arenas, 25) == arenas


def test_the_sample_gives_every_family_its_turn_even_when_a_regular_step_would_miss_some():
    # Families cycle a, b, c, d: every 4th arena (n = 16, K = 4) would all be family a.
    arenas = [(Path(f"arena-{i:04d}.toml"), {"family": "abcd"[i % 4]}) for i in range(16)]
    picked = sample_arenas(arenas, 6)
    assert sorted(meta["family"] for _, meta in picked) == ["a", "a", "b", "b", "c", "d"]
    assert [p.stem for p, _ in picked] == [
        "arena-0000",
        "arena-0001",
        "arena-0002",
        "arena-0003",
        "arena-0008",
        "arena-0009",
    ]  # a and b: their 1st and 3rd of 4


# ---------------------------------------------------------------- guards


def _job(tmp_path: Path, seed: int, run_timeout_s: float | None = 600.0) -> TrialJob:
    return TrialJob(tmp_path / "easy.toml", "rovernav", seed, tmp_path / "runs" / f"easy-s{seed}", 30.0, run_timeout_s)


def _raise_on_seed_1(scenario_path, strategy, seed, out_dir, max_time_s, run_timeout_s):
    if seed == 1:
        raise RuntimeError("the planner fell over")
    return {"seed": seed, "outcome": "stand-in"}


def _hang_on_seed_1(scenario_path, strategy, seed, out_dir, max_time_s, run_timeout_s):
    if seed == 1:
        time.sleep(3600)  # a run that never returns to the simulator's loop
    return {"seed": seed, "outcome": "stand-in"}


def test_a_run_that_raises_is_recorded_as_an_error_with_its_traceback_and_the_others_go_on(tmp_path):
    rows = run_jobs([_job(tmp_path, 1), _job(tmp_path, 2)], workers=0, trial=_raise_on_seed_1)
    assert [(r["seed"], r["outcome"]) for r in rows] == [(1, "error"), (2, "stand-in")]
    assert rows[0]["failed"] and "the planner fell over" in rows[0]["error"]
    assert "RuntimeError" in (tmp_path / "runs" / "easy-s1" / "error.txt").read_text()


def test_a_run_past_its_wall_clock_budget_stops_itself_and_is_recorded_as_hung(tmp_path):
    (tmp_path / "easy.toml").write_text(EASY)
    row = run_trial(str(tmp_path / "easy.toml"), "rovernav", 1, str(tmp_path / "run"), 30.0, run_timeout_s=1e-6)
    assert row["outcome"] == "hung" and row["failed"] and "--run-timeout" in row["error"]
    assert _strict_json(tmp_path / "run" / "report.json")["outcome"] == "hung"
    assert (tmp_path / "run" / "summary.png").is_file()


@pytest.mark.slow
def test_on_a_dask_cluster_a_run_that_never_returns_is_killed_and_the_benchmark_goes_on(tmp_path):
    jobs = [_job(tmp_path, 1, run_timeout_s=0.5), _job(tmp_path, 2, run_timeout_s=0.5)]
    rows = run_jobs(jobs, workers=1, trial=_hang_on_seed_1, hang_grace_s=0.5)
    assert sorted((r["seed"], r["outcome"]) for r in rows) == [(1, "hung"), (2, "stand-in")]


# ---------------------------------------------------------------- the command


@pytest.mark.parametrize(
    "make, extra",
    [
        (lambda d: d / "missing", []),
        (lambda d: _arenas(d / "empty"), []),  # a folder without *.toml
        (lambda d: _arenas(d / "arenas", easy=EASY), ["--seeds", "0"]),
        (lambda d: _arenas(d / "arenas", easy=EASY), ["--sample", "0"]),
        (lambda d: _arenas(d / "arenas", easy=EASY), ["--fail-on", "crash,slowness"]),
        (lambda d: _arenas(d / "arenas", bad="version = 1\n[arena]\nwidth_m = -1\n"), []),
        (lambda d: _arenas(d / "arenas", easy=EASY), ["--scheduler", "nonsense://nowhere"]),
    ],
)
def test_bad_input_ends_with_a_one_line_error_and_status_2(tmp_path, capsys, make, extra):
    try:
        code = main(["trials", str(make(tmp_path)), "--out", str(tmp_path / "out"), *extra])
    except SystemExit as exc:  # a flag refused by the parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rovernav trials: ") and "\n" not in err and "Traceback" not in err


def test_an_unreachable_scheduler_is_bad_input(tmp_path, capsys):
    import dask

    arenas = _arenas(tmp_path / "arenas", easy=EASY)
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        assert main(["trials", str(arenas), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "cannot use the dask scheduler" in capsys.readouterr().err


def _arenas(folder: Path, **files: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / f"{name}.toml").write_text(text)
    return folder


@pytest.mark.mission
def test_a_serial_benchmark_on_two_tiny_arenas_writes_every_output(tmp_path, capsys):
    arenas = _arenas(tmp_path / "arenas", easy=EASY, enclosed=ENCLOSED)
    out = tmp_path / "out"
    rc = main(
        [
            "trials",
            str(arenas),
            "--serial",
            "--strategy",
            "rovernav",
            "--seeds",
            "1",
            "--max-time",
            "60",
            "--out",
            str(out),
        ]
    )
    captured = capsys.readouterr()
    assert rc in (0, 1), captured.err
    printed = captured.out
    assert "[2/2]" in printed
    summary = _strict_json(out / "trials.json")
    rows = {r["arena"]: r for r in summary["rows"]}
    assert set(rows) == {"easy", "enclosed"} and summary["headline"]["rovernav"]["runs"] == 2
    assert rows["easy"]["reached"] and rows["easy"]["success"] and not rows["easy"]["failed"]
    assert (rows["easy"]["family"], rows["easy"]["solvable"]) == ("unlabelled", True)  # by the clairvoyant planner
    assert (rows["enclosed"]["family"], rows["enclosed"]["band"], rows["enclosed"]["solvable"]) == (
        "enclosure",
        "hard",
        False,
    )
    assert rc == (1 if summary["gate"]["violations"] else 0)
    with (out / "trials.csv").open() as f:
        assert sorted(r["arena"] for r in csv.DictReader(f)) == ["easy", "enclosed"]
    md = (out / "trials.md").read_text()
    assert "## Headline" in md and "## rovernav by family" in md and "## rovernav by difficulty band" in md
    assert "| enclosure | 1 |" in md and "| hard | 1 |" in md
    for arena in ("easy", "enclosed"):
        run = out / "runs" / "rovernav" / f"{arena}-s1"
        assert _strict_json(run / "report.json")["scenario"] == arena and (run / "summary.png").is_file()
        assert rows[arena]["report"] == f"runs/rovernav/{arena}-s1/report.json"
    gallery = sorted(p.name for p in (out / "gallery").iterdir())
    assert gallery == ([] if not rows["enclosed"]["failed"] else ["rovernav-enclosed-s1.png"])
    assert (out / "gallery.md").is_file()


@pytest.mark.mission
@pytest.mark.slow
def test_a_benchmark_on_a_one_worker_local_dask_cluster(tmp_path, capsys):
    arenas = _arenas(tmp_path / "arenas", easy=EASY)
    out = tmp_path / "out"
    assert main(["trials", str(arenas), "--workers", "1", "--max-time", "60", "--out", str(out)]) == 0
    assert "local dask cluster of 1 worker" in capsys.readouterr().out
    (row,) = _strict_json(out / "trials.json")["rows"]
    assert row["reached"] and row["success"] and row["outcome"] == "reached"


def test_a_job_carries_its_planner_to_the_run(tmp_path):
    from rovernav.evaluation.jobs import make_jobs

    arena = tmp_path / "a.toml"
    (job,) = make_jobs([(arena, None)], ["rovernav"], [1], tmp_path, 30.0, None)
    assert job.planner == "astar" and len(job.args) == 6  # as before: the default adds nothing
    (job,) = make_jobs([(arena, None)], ["rovernav"], [1], tmp_path, 30.0, None, None, "theta")
    assert job.args[6:] == (None, "theta")
