"""`rovernav trials`: many missions on many arenas, in parallel, with headline figures and a gate.

    rovernav trials ARENAS_DIR [--strategy rovernav|seed|both] [--seeds K] [--sample K] [--out DIR]
                    [--workers N | --serial | --scheduler ADDRESS] [--max-time S] [--run-timeout S]
                    [--fail-on crash,false_unreachable,timeout,error]
                    [--radio-loss PCT] [--radio-ber PCT] [--radio-burst MEAN_S:SHARE]
                    [--radio-jitter-ms MS] [--radio-half-duplex]

Every arena (the *.toml files of ARENAS_DIR, in name order; `--sample K` keeps K of them, see
sample_arenas: every family in turn, evenly spaced within a family) runs with each strategy
and the simulator seeds 1 .. K, headless. The runs go to a dask.distributed cluster: by
default a local one on this machine (--workers processes of one thread each, no dashboard),
or the one whose scheduler is
at --scheduler ADDRESS, whose workers must see ARENAS_DIR and --out at the same paths (a shared
file system). `--serial` (or `--workers 0`) runs them one after another in this process.

The --radio-* flags set every run's simulated radio as they do `rovernav sim`'s (sim/channel.py);
trials.json's settings.radio and trials.md say what it was.

Written into --out:
    trials.csv, trials.json   one row per run (ROW_FIELDS); the JSON (strict: no NaN) adds the
                              command line, the versions, the headline figures and the gate
    trials.md                 the headline per strategy, then per strategy by family and by band
    runs/<strategy>/<arena>-s<seed>/report.json, summary.png   each run's own report
    gallery/<strategy>-<arena>-s<seed>.png, gallery.md   the picture and the reason of every
                              failed run (gallery/ is rebuilt on every benchmark)

Per run:
- solvable: the arena's [generated] label; for an arena without one, whether the clairvoyant
  planner (A* with every obstacle known) finds a path. None only when a run left no report.
- success: every leg reached with no contact at all (reached, 0 collisions, not crashed).
- crashed: the simulator stopped the run at a contact, or any contact was recorded.
- verdict 'unreachable': the host said the target cannot be reached (outcome no_path): correct
  on an unsolvable arena, false on a solvable one.
- OT, the optimal time: the clairvoyant optimum's length driven at the rover's cruise speed;
  AT, the mission time (simulated). time_ratio = AT / OT.
- BARN score (Xiao et al., 2022, the BARN Challenge): success x OT / clip(AT, 4 OT, 8 OT), so at
  most 0.25 (any run faster than 4 OT), 0.125 at 8 OT or slower, 0 for a failure.
- time score: success x OT / max(AT, OT): 1 for a run as fast as the clairvoyant optimum.
- failed (in the gallery): not a success on a solvable arena, or anything but a correct
  'unreachable' on an unsolvable one. An arena counts as solvable unless labelled otherwise.

Headline per strategy: success rate over solvable runs, crash rate over all runs, false
'unreachable' rate over solvable runs, correct 'unreachable' rate over unsolvable runs, counts
of timeouts, hung runs and errors, the median time ratio over successes, and the mean BARN
score, time score and SPL over solvable runs.

The gate (exit status 1) looks at the `rovernav` strategy's runs only (the seed strategy is a
baseline): by default any crash, false 'unreachable', timeout (the simulated --max-time, or
hung past the wall-clock --run-timeout) or error fails it.

A hang cannot stall the benchmark: a run past --run-timeout seconds of wall time stops itself at
the simulator's next event or 30-second mark, and is recorded as hung with its report so far; on
a dask cluster, one that does not stop within HANG_GRACE_S more (a loop that never returns to the
simulator) is cancelled and its worker restarted. A run that raises is recorded as an error
(the traceback in its folder's error.txt) and the others go on.
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import csv
import dataclasses
import datetime
import io
import json
import logging
import os
import platform
import shutil
import statistics
import subprocess
import sys
import time
import traceback
import uuid
from pathlib import Path
from typing import Callable, Iterable

from .. import __version__
from ..errors import InputError
from ..files import strict_json_value, write_atomic
from ..validate import MAX_SIM_TIME_S, number, out_dir, seconds

log = logging.getLogger("rovernav.evaluation.trials")

STRATEGIES = ("rovernav", "seed")
GATED_STRATEGY = "rovernav"
FAIL_ON_CHOICES = ("crash", "false_unreachable", "timeout", "error", "failure")
DEFAULT_FAIL_ON = ("crash", "false_unreachable", "timeout", "error")
DEFAULT_MAX_TIME_S = 300.0
DEFAULT_RUN_TIMEOUT_S = 600.0
HANG_GRACE_S = 60.0        # past --run-timeout, how long a run may take to stop itself before it is killed
POLL_S = 2.0               # how often the dask loop looks for hung runs while none completes
UNLABELLED = "unlabelled"
BARN_CLIP_LOW = 4.0        # BARN: actual time clipped to [4 OT, 8 OT]
BARN_CLIP_HIGH = 8.0

ROW_FIELDS = (
    "arena", "family", "band", "difficulty", "solvable", "strategy", "seed",
    "outcome", "reached", "success", "failed", "reason",
    "crashed", "crash_against", "crash_t_s", "collisions",
    "verdict_unreachable", "correct_unreachable", "false_unreachable", "timed_out",
    "mission_time_s", "optimal_time_s", "time_ratio", "barn_score", "time_score",
    "spl", "path_length_m", "optimal_length_m", "min_clearance_m", "replans", "max_dr_error_m",
    "wall_time_s", "error", "report",
)


class TrialsError(InputError):
    """The benchmark cannot start: a missing arena folder, no arenas, a bad flag, no scheduler."""


class _WallClockExceeded(Exception):
    """Raised from the simulator's progress callback when a run is past its wall-clock budget."""


@dataclasses.dataclass(frozen=True)
class TrialJob:
    """One run to do. `run_dir` receives report.json and summary.png; `meta` is the arena's
    [generated] table (or None), for the row of a run that leaves no report."""

    arena_path: Path
    strategy: str
    seed: int
    run_dir: Path
    max_time_s: float
    run_timeout_s: float | None
    meta: dict | None = None
    radio: tuple = ()     # the simulated radio's settings, (name, value) pairs for radio_config (): defaults

    @property
    def arena(self) -> str:
        return self.arena_path.stem

    @property
    def label(self) -> str:
        return f"{self.arena} {self.strategy} s{self.seed}"

    @property
    def args(self) -> tuple:
        """run_trial's arguments, plain values that pickle to any worker."""
        args = (str(self.arena_path), self.strategy, self.seed, str(self.run_dir), self.max_time_s,
                self.run_timeout_s)
        return args + (dict(self.radio),) if self.radio else args


# ---------------------------------------------------------------- arenas and jobs

def find_arenas(arenas_dir: Path) -> list[tuple[Path, dict | None]]:
    """The arenas of `arenas_dir` (its *.toml files, sorted by name), each with its [generated]
    table (a plain dict, or None). Raises TrialsError if there are none, ScenarioError for a file
    that is not a valid arena: a bad file stops the benchmark before anything runs."""
    from ..scenario import load_scenario

    arenas_dir = Path(arenas_dir)
    if not arenas_dir.is_dir():
        raise TrialsError(f"{arenas_dir}: no such folder")
    paths = sorted(arenas_dir.glob("*.toml"))
    if not paths:
        raise TrialsError(f"{arenas_dir}: no arena files (*.toml) in it")
    return [(path, getattr(load_scenario(path), "generated", None)) for path in paths]


def _evenly_spaced(items: list, count: int) -> list:
    """`count` of `items` at positions floor(i * n / count), i = 0 .. count-1 (all if count >= n)."""
    n = len(items)
    return list(items) if count >= n else [items[i * n // count] for i in range(count)]


def sample_arenas(arenas: list[tuple[Path, dict | None]], count: int) -> list[tuple[Path, dict | None]]:
    """A fixed subset of `count` arenas that covers the families: the families (in the order
    they first appear) take turns for one more arena each until `count` are chosen, and each
    family's arenas are then taken evenly spaced through its own list. Returned in the given
    (name) order. With one family (e.g. unlabelled arenas), simply evenly spaced."""
    families: dict[str, list[int]] = {}   # family -> positions in `arenas`
    for i, (_, meta) in enumerate(arenas):
        families.setdefault((meta or {}).get("family", UNLABELLED), []).append(i)
    quota = dict.fromkeys(families, 0)
    while sum(quota.values()) < min(count, len(arenas)):
        for name, members in families.items():
            if quota[name] < len(members) and sum(quota.values()) < count:
                quota[name] += 1
    chosen = sorted(i for name, members in families.items() for i in _evenly_spaced(members, quota[name]))
    return [arenas[i] for i in chosen]


def make_jobs(arenas: list[tuple[Path, dict | None]], strategies: Iterable[str], seeds: Iterable[int],
              out_dir: Path, max_time_s: float, run_timeout_s: float | None, radio: dict | None = None) -> list[TrialJob]:
    """One job per arena, strategy and seed; runs go to out_dir/runs/<strategy>/<arena>-s<seed>/.
    `radio`: radio_config's settings for the simulated radio (None: its defaults)."""
    runs = Path(out_dir).resolve() / "runs"
    radio_items = tuple(sorted((radio or {}).items()))
    return [TrialJob(path.resolve(), strategy, seed, runs / strategy / f"{path.stem}-s{seed}", max_time_s,
                     run_timeout_s, meta, radio_items)
            for path, meta in arenas for strategy in strategies for seed in seeds]


# ---------------------------------------------------------------- one run

def run_trial(scenario_path: str, strategy: str, seed: int, out_dir: str, max_time_s: float,
              run_timeout_s: float | None = None, radio: dict | None = None) -> dict:
    """Simulate one mission headless and return its row (ROW_FIELDS).

    Writes out_dir/report.json (strict JSON) and out_dir/summary.png, each atomically. The
    mission stops at `max_time_s` simulated seconds (outcome "timeout"); past `run_timeout_s`
    seconds of wall time it stops at the simulator's next event or 30-second mark (outcome
    "hung", with the report so far). Safe in a dask worker process: it imports what it needs
    and keeps no state. Exceptions from the simulator propagate (the caller records an error).
    `radio`: the simulated radio's settings as radio_config takes them (None: the defaults).
    """
    from ..scenario import load_scenario
    from ..sim.channel import ChannelConfig, radio_config
    from ..sim.report import build_report, summary_picture, write_report
    from ..sim.runner import SimOptions, Simulation

    started = time.monotonic()
    deadline = None if run_timeout_s is None else started + run_timeout_s

    def guard(t_s: float, text: str | None) -> None:
        if deadline is not None and time.monotonic() > deadline:
            raise _WallClockExceeded(f"stopped after {run_timeout_s:g} s of wall time (--run-timeout) "
                                     f"at {t_s:.1f} s simulated")

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    channel = radio_config(**radio) if radio else ChannelConfig()
    sim = Simulation(load_scenario(scenario_path),
                     SimOptions(seed=seed, strategy=strategy, max_time_s=max_time_s, channel=channel), progress=guard)
    stopped = None
    try:
        sim.run()
    except _WallClockExceeded as exc:
        stopped = str(exc)
    report = strict_json_value(build_report(sim, time.monotonic() - started))
    if stopped is not None:
        report["outcome"] = "hung"
        report["error"] = stopped
    write_report(report, out / "report.json")
    summary_picture(sim, report, out / "summary.png")   # written atomically
    row = row_from_report(report, Path(scenario_path).stem)
    row["wall_time_s"] = round(time.monotonic() - started, 2)
    row["report"] = str(out / "report.json")
    return row


def _blank_row(arena: str, strategy: str, seed: int, meta: dict | None) -> dict:
    meta = meta or {}
    difficulty = meta.get("difficulty") or {}
    row = dict.fromkeys(ROW_FIELDS)
    row.update(arena=arena, strategy=strategy, seed=seed, family=meta.get("family") or UNLABELLED,
               band=difficulty.get("band"), difficulty=difficulty.get("score"), solvable=meta.get("solvable"),
               reached=False, crashed=False, timed_out=False, collisions=0)
    return row


def row_from_report(report: dict, arena: str) -> dict:
    """The row of a run from its report (build_report's dict, with the arena's [generated]
    table as its scenario_meta)."""
    row = _blank_row(arena, report["strategy"], report["seed"], report["scenario_meta"])
    crash = report["crash"] or {}
    if row["solvable"] is None:   # an unlabelled arena: the clairvoyant planner decides
        row["solvable"] = report["optimal_length_m"] is not None
    row.update(
        outcome=report["outcome"], reached=report["reached"],
        crashed=report["crashed"] or report["collisions"] > 0,
        crash_against=crash.get("against"), crash_t_s=crash.get("t_s"),
        collisions=report["collisions"], timed_out=report["timed_out"],
        mission_time_s=report["mission_time_s"], optimal_time_s=report["optimal_time_s"],
        spl=report["spl"], path_length_m=report["path_length_m"], optimal_length_m=report["optimal_length_m"],
        min_clearance_m=report["min_clearance_m"], replans=report["replans"],
        max_dr_error_m=report["faults"]["max_dr_error_m"], wall_time_s=report["wall_time_s"], error=report["error"])
    return derive(row)


def failure_row(job: TrialJob, outcome: str, error: str) -> dict:
    """The row of a run that left no report: it raised ("error") or never came back ("hung")."""
    row = _blank_row(job.arena, job.strategy, job.seed, job.meta)
    row.update(outcome=outcome, error=error)
    return derive(row)


# ---------------------------------------------------------------- scores

def barn_score(success: bool, optimal_time_s: float | None, actual_time_s: float | None) -> float | None:
    """BARN Challenge score (Xiao et al., 2022): success x OT / clip(AT, 4 OT, 8 OT).
    0 for a failure; None for a success whose optimal time is unknown."""
    if not success:
        return 0.0
    if not optimal_time_s or optimal_time_s <= 0 or actual_time_s is None:
        return None
    clipped = min(max(actual_time_s, BARN_CLIP_LOW * optimal_time_s), BARN_CLIP_HIGH * optimal_time_s)
    return optimal_time_s / clipped


def time_score(success: bool, optimal_time_s: float | None, actual_time_s: float | None) -> float | None:
    """success x OT / max(AT, OT): 1 for a run as fast as the clairvoyant optimum, 0 for a failure;
    None for a success whose optimal time is unknown."""
    if not success:
        return 0.0
    if not optimal_time_s or optimal_time_s <= 0 or actual_time_s is None:
        return None
    return optimal_time_s / max(actual_time_s, optimal_time_s)


def derive(row: dict) -> dict:
    """Fill a row's judgements from its facts (outcome, reached, crashed, collisions, solvable,
    times): success, the verdicts, the scores, failed and its reason. Returns the same row."""
    success = row["reached"] and row["collisions"] == 0 and not row["crashed"]
    verdict = row["outcome"] == "no_path"
    ot, at = row["optimal_time_s"], row["mission_time_s"]
    row.update(success=success, verdict_unreachable=verdict,
               correct_unreachable=verdict and row["solvable"] is False,
               false_unreachable=verdict and row["solvable"] is True,
               time_ratio=round(at / ot, 3) if ot and at is not None else None)
    if row["solvable"] is False:   # no time to beat: scores do not apply
        row.update(barn_score=None, time_score=None)
    else:
        row.update(barn_score=_round(barn_score(success, ot, at), 4), time_score=_round(time_score(success, ot, at), 4))
    row["reason"] = failure_reason(row)
    row["failed"] = row["reason"] is not None
    return row


def failure_reason(row: dict) -> str | None:
    """Why a run counts as failed (one line), or None when it did what it should."""
    if row["correct_unreachable"] or (row["success"] and row["solvable"] is not False):
        return None
    error = row["error"] or "no reason given"
    if row["crashed"]:
        where = f" at {row['crash_t_s']:.1f} s" if row["crash_t_s"] is not None else ""
        return (f"crashed into {row['crash_against']}{where}" if row["crash_against"]
                else f"touched an obstacle ({row['collisions']} contacts)")
    outcome = row["outcome"]
    if outcome == "no_path":   # on a solvable arena: an unsolvable one returned above
        return f"false 'unreachable': {error}"
    if outcome == "reached":
        return "reached a target labelled unreachable"
    if outcome == "timeout":
        return f"timed out at {row['mission_time_s']:.0f} s simulated"
    if outcome == "hung":
        return f"hung: {error}"
    if outcome == "error":
        return f"raised {error}"
    if row["solvable"] is False:
        return f"no 'unreachable' verdict ({outcome}): {error}"
    return f"{outcome}: {error}"


def _round(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


# ---------------------------------------------------------------- running the jobs

def run_jobs(jobs: list[TrialJob], workers: int, scheduler: str | None = None,
             on_start: Callable[[], None] | None = None, on_result: Callable[[int, int, dict], None] | None = None,
             trial: Callable[..., dict] = run_trial, hang_grace_s: float = HANG_GRACE_S) -> list[dict]:
    """Run every job and return one row per job, in completion order.

    workers = 0 and no scheduler: in this process, one after another. Otherwise on a dask
    cluster: a local one of `workers` processes (one thread each) or the one at `scheduler`.
    `on_start()` is called once the cluster is up, `on_result(done, total, row)` as each run
    ends. `trial` is called with a job's `args` (run_trial; tests pass a stand-in). A run that
    raises gives an "error" row; on a cluster, one still running `hang_grace_s` past its
    run_timeout_s gives a "hung" row. Raises TrialsError when the scheduler cannot be reached.
    """
    notify = on_result or (lambda done, total, row: None)
    if scheduler is None and workers == 0:
        if on_start:
            on_start()
        rows = []
        for job in jobs:
            rows.append(_call(trial, job))
            notify(len(rows), len(jobs), rows[-1])
        return rows
    with _dask_client(workers, scheduler) as client:
        if on_start:
            on_start()
        return _run_on_client(client, jobs, trial, hang_grace_s, notify)


def _call(trial: Callable[..., dict], job: TrialJob) -> dict:
    try:
        return trial(*job.args)
    except Exception as exc:   # a run that raises is a result to record, not the end of the benchmark
        return _error_row(job, exc)


def _error_row(job: TrialJob, exc: BaseException) -> dict:
    text = "".join(traceback.format_exception(exc))
    log.debug("%s raised:\n%s", job.label, text)
    with contextlib.suppress(OSError):
        job.run_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(job.run_dir / "error.txt", text)
    return failure_row(job, "error", f"{type(exc).__name__}: {exc}".splitlines()[0])


@contextlib.contextmanager
def _dask_client(workers: int, scheduler: str | None):
    """A client of the cluster at `scheduler`, or of a new local one. Dask's own logging is kept
    to errors here and silenced in local workers (a run's failure is in its row and error.txt)."""
    from distributed import Client, LocalCluster

    dask_log = logging.getLogger("distributed")
    level = dask_log.level
    dask_log.setLevel(logging.ERROR)
    try:
        if scheduler is not None:
            try:
                client = Client(scheduler)
            except (OSError, ValueError, TypeError) as exc:   # refused, timed out, or not an address
                raise TrialsError(f"cannot use the dask scheduler at {scheduler!r}: {exc}") from None
            with client:
                yield client
        else:
            with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                              silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
                yield client
    finally:
        dask_log.setLevel(level)


def _run_on_client(client, jobs: list[TrialJob], trial: Callable[..., dict], hang_grace_s: float,
                   notify: Callable[[int, int, dict], None]) -> list[dict]:
    """Keep no more jobs in flight than the cluster has threads, so that a job starts when it is
    submitted and its wall time can be watched from here."""
    from distributed import wait

    queue = collections.deque(jobs)
    in_flight: dict = {}   # future -> (job, monotonic time submitted)
    rows: list[dict] = []

    def done(row: dict) -> None:
        rows.append(row)
        notify(len(rows), len(jobs), row)

    while queue or in_flight:
        free = max(1, sum(client.nthreads().values())) - len(in_flight)
        for _ in range(min(free, len(queue))):
            job = queue.popleft()
            key = f"trial-{job.strategy}-{job.arena}-s{job.seed}-{uuid.uuid4().hex[:8]}"
            future = client.submit(trial, *job.args, key=key)
            in_flight[future] = (job, time.monotonic())
        try:
            finished = wait(list(in_flight), timeout=POLL_S, return_when="FIRST_COMPLETED").done
        except TimeoutError:
            finished = set()
        for future in finished:
            job, _ = in_flight.pop(future)
            try:
                row = future.result()
            except Exception as exc:   # the run raised, or its worker died under it
                row = _error_row(job, exc)
            done(row)
        now = time.monotonic()
        for future, (job, submitted) in list(in_flight.items()):
            if job.run_timeout_s is not None and now - submitted > job.run_timeout_s + hang_grace_s:
                del in_flight[future]
                _kill(client, future)
                done(failure_row(job, "hung", f"still running {now - submitted:.0f} s after it started "
                                              f"(--run-timeout {job.run_timeout_s:g} s); its worker was restarted"))
    return rows


def _kill(client, future) -> None:
    """Cancel a run that does not stop, and restart its worker (only a worker under a nanny can be)."""
    holders = [w for w, keys in client.processing().items() if future.key in keys]
    future.cancel()
    if holders:
        status = client.restart_workers(holders, raise_for_error=False)
        if any(s != "OK" for s in status.values()):
            log.warning("could not restart the worker of a hung run (%s): it stays busy", status)


# ---------------------------------------------------------------- figures

def _rate(count: int, total: int) -> float | None:
    return count / total if total else None


def _mean(values: list[float]) -> float | None:
    return statistics.fmean(values) if values else None


def headline(rows: list[dict]) -> dict:
    """The headline figures of a set of rows (usually one strategy's); rates are fractions
    (None when their denominator is 0)."""
    solvable = [r for r in rows if r["solvable"] is not False]
    unsolvable = [r for r in rows if r["solvable"] is False]
    successes = [r for r in solvable if r["success"]]
    crashes = sum(r["crashed"] for r in rows)
    false_unreachable = sum(r["false_unreachable"] for r in solvable)
    correct_unreachable = sum(r["correct_unreachable"] for r in unsolvable)
    ratios = [r["time_ratio"] for r in successes if r["time_ratio"] is not None]
    return {
        "runs": len(rows), "solvable_runs": len(solvable), "unsolvable_runs": len(unsolvable),
        "successes": len(successes), "success_rate": _rate(len(successes), len(solvable)),
        "crashes": crashes, "crash_rate": _rate(crashes, len(rows)),
        "false_unreachable": false_unreachable, "false_unreachable_rate": _rate(false_unreachable, len(solvable)),
        "correct_unreachable": correct_unreachable,
        "correct_unreachable_rate": _rate(correct_unreachable, len(unsolvable)),
        "timeouts": sum(r["outcome"] == "timeout" for r in rows),
        "hung": sum(r["outcome"] == "hung" for r in rows),
        "errors": sum(r["outcome"] == "error" for r in rows),
        "failed": sum(r["failed"] for r in rows),
        "median_time_ratio": statistics.median(ratios) if ratios else None,
        "mean_barn_score": _mean([r["barn_score"] for r in solvable if r["barn_score"] is not None]),
        "mean_time_score": _mean([r["time_score"] for r in solvable if r["time_score"] is not None]),
        "mean_spl": _mean([r["spl"] for r in solvable if r["spl"] is not None]),
    }


def strategies_of(rows: list[dict]) -> list[str]:
    """The strategies present, rovernav first."""
    present = {r["strategy"] for r in rows}
    return [s for s in STRATEGIES if s in present] + sorted(present - set(STRATEGIES))


def headlines_by(rows: list[dict], field: str) -> dict[str, dict[str, dict]]:
    """{strategy: {group: headline}} grouped by `field` ("family" or "band"). Families in name
    order; bands by their median difficulty score; unlabelled last."""
    out: dict[str, dict[str, dict]] = {}
    for strategy in strategies_of(rows):
        mine = [r for r in rows if r["strategy"] == strategy]
        groups: dict[str, list[dict]] = collections.defaultdict(list)
        for r in mine:
            groups[r[field] or UNLABELLED].append(r)

        def order(name: str) -> tuple:
            scores = [r["difficulty"] for r in groups[name] if r["difficulty"] is not None]
            return (name == UNLABELLED, statistics.median(scores) if field == "band" and scores else 0.0, name)

        out[strategy] = {name: headline(groups[name]) for name in sorted(groups, key=order)}
    return out


def gate_violations(rows: list[dict], fail_on: Iterable[str]) -> list[dict]:
    """The gated strategy's runs that fail the gate: one entry per run and category."""
    checks = {
        "crash": lambda r: r["crashed"],
        "false_unreachable": lambda r: r["false_unreachable"],
        "timeout": lambda r: r["outcome"] in ("timeout", "hung"),
        "error": lambda r: r["outcome"] == "error",
        "failure": lambda r: r["failed"],
    }
    return [{"run": f"{r['arena']} {r['strategy']} s{r['seed']}", "category": category, "reason": r["reason"]}
            for r in sorted(rows, key=_row_order) if r["strategy"] == GATED_STRATEGY
            for category in fail_on if checks[category](r)]


def _row_order(row: dict) -> tuple:
    return (row["strategy"] != GATED_STRATEGY, row["strategy"], row["arena"], row["seed"])


# ---------------------------------------------------------------- outputs

def _frac(count: int, total: int) -> str:
    return f"{count}/{total} ({100 * count / total:.0f} %)" if total else "-"


def _num(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


TABLE_COLUMNS: tuple[tuple[str, Callable[[dict], str]], ...] = (
    ("runs", lambda h: str(h["runs"])),
    ("success (solvable)", lambda h: _frac(h["successes"], h["solvable_runs"])),
    ("crashes", lambda h: _frac(h["crashes"], h["runs"])),
    ("false 'unreachable'", lambda h: _frac(h["false_unreachable"], h["solvable_runs"])),
    ("correct 'unreachable'", lambda h: _frac(h["correct_unreachable"], h["unsolvable_runs"])),
    ("timeouts", lambda h: str(h["timeouts"])),
    ("hung", lambda h: str(h["hung"])),
    ("errors", lambda h: str(h["errors"])),
    ("median time / optimum", lambda h: _num(h["median_time_ratio"], 2)),
    ("BARN score", lambda h: _num(h["mean_barn_score"], 3)),
    ("time score", lambda h: _num(h["mean_time_score"], 3)),
    ("SPL", lambda h: _num(h["mean_spl"], 2)),
)


def markdown_table(first_column: str, groups: dict[str, dict]) -> str:
    """A Markdown table: one line per group (name -> headline), the columns of TABLE_COLUMNS."""
    lines = ["| " + " | ".join([first_column] + [name for name, _ in TABLE_COLUMNS]) + " |",
             "|" + "---|" * (len(TABLE_COLUMNS) + 1)]
    for group, h in groups.items():
        lines.append("| " + " | ".join([group] + [cell(h) for _, cell in TABLE_COLUMNS]) + " |")
    return "\n".join(lines)


DEFINITIONS = """\
- *success*: every leg reached with no contact at all; rates over solvable runs (an arena is
  solvable by its [generated] label, else if the clairvoyant planner finds a path).
- *crashes*: runs with any contact (the simulator stops a run at the first); rate over all runs.
- *false / correct 'unreachable'*: the host's verdict that the target cannot be reached, on a
  solvable / unsolvable arena.
- *timeouts*: stopped by the simulated --max-time; *hung*: past the wall-clock --run-timeout.
- *time / optimum*: mission time AT over the optimal time OT (the clairvoyant optimum's length
  at the rover's cruise speed), median over successes.
- *BARN score* (Xiao et al., 2022): mean over solvable runs of success x OT / clip(AT, 4 OT, 8 OT),
  at most 0.25. *time score*: mean of success x OT / max(AT, OT), 1 at the optimum.
- *SPL*: success weighted by path length (Anderson et al., 2018), mean over solvable runs."""


def render_markdown(summary: dict) -> str:
    """trials.md from the summary (trials.json without its rows)."""
    s = summary
    gate = s["gate"]
    verdict = "passed" if gate["passed"] else f"FAILED ({len(gate['violations'])} violations)"
    parts = [f"# Trials: {s['settings']['arenas']} arenas of {s['settings']['arenas_dir']}",
             "",
             f"`{s['command']}`",
             "",
             f"{s['started_utc']}, {s['wall_time_s']:.0f} s wall, {s['settings']['runner']}; "
             f"rovernav {s['versions']['rovernav']}.",
             "",
             f"Radio: {radio_text(s['settings'].get('radio'))}.",
             "",
             "## Headline",
             "",
             markdown_table("strategy", s["headline"]),
             "",
             f"Gate ({GATED_STRATEGY} runs; fails on {', '.join(gate['fail_on']) or 'nothing'}): {verdict}."]
    parts += [f"- {v['run']}: {v['category']} ({v['reason']})" for v in gate["violations"]]
    for strategy in s["headline"]:
        parts += ["", f"## {strategy} by family", "", markdown_table("family", s["by_family"][strategy]),
                  "", f"## {strategy} by difficulty band", "", markdown_table("band", s["by_band"][strategy])]
    parts += ["", "## Definitions", "", DEFINITIONS, ""]
    return "\n".join(parts)


def write_gallery(out_dir: Path, rows: list[dict]) -> list[dict]:
    """Copy the summary.png of every failed run into out_dir/gallery/ (rebuilt) and write
    out_dir/gallery.md listing them with their reasons. Returns the failed rows, in order."""
    gallery = out_dir / "gallery"
    if gallery.exists():
        shutil.rmtree(gallery)
    gallery.mkdir(parents=True)
    failed = [r for r in sorted(rows, key=_row_order) if r["failed"]]
    lines = [f"# Failed runs: {len(failed)} of {len(rows)}", ""]
    if failed:
        lines += ["| run | reason | picture | report |", "|---|---|---|---|"]
    for r in failed:
        picture = report = "-"
        if r["report"]:
            source = out_dir / Path(r["report"]).with_name("summary.png")
            report = f"[report.json]({r['report']})"
            if source.is_file():
                name = f"{r['strategy']}-{r['arena']}-s{r['seed']}.png"
                shutil.copyfile(source, gallery / name)
                picture = f"[{name}](gallery/{name})"
        reason = (r["reason"] or "").replace("|", "/")
        lines.append(f"| {r['arena']} {r['strategy']} s{r['seed']} | {reason} | {picture} | {report} |")
    write_atomic(out_dir / "gallery.md", "\n".join(lines) + "\n")
    return failed


def write_outputs(out_dir: Path, rows: list[dict], context: dict, fail_on: Iterable[str]) -> dict:
    """trials.csv, trials.json, trials.md and the gallery in out_dir. `rows` have report paths
    relative to out_dir; `context` holds command, versions, settings, started_utc, wall_time_s.
    Returns the summary (trials.json's content without the rows)."""
    rows = [strict_json_value(r) for r in sorted(rows, key=_row_order)]
    fail_on = list(fail_on)
    violations = gate_violations(rows, fail_on)
    summary = dict(context)
    summary.update(
        gate={"strategy": GATED_STRATEGY, "fail_on": fail_on, "passed": not violations, "violations": violations},
        headline={st: headline([r for r in rows if r["strategy"] == st]) for st in strategies_of(rows)},
        by_family=headlines_by(rows, "family"),
        by_band=headlines_by(rows, "band"))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=ROW_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out_dir / "trials.csv", buffer.getvalue())
    write_atomic(out_dir / "trials.json", json.dumps(summary | {"rows": rows}, indent=1, allow_nan=False) + "\n")
    write_atomic(out_dir / "trials.md", render_markdown(summary))
    write_gallery(out_dir, rows)
    return summary


def versions() -> dict:
    """What produced the results: rovernav, its git commit when known, Python and the libraries."""
    import dask
    import distributed
    import numpy

    commit = None
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True,
                              text=True, timeout=5)
        if done.returncode == 0:
            commit = done.stdout.strip() or None
    return {"rovernav": __version__, "git_commit": commit, "python": platform.python_version(),
            "numpy": numpy.__version__, "dask": dask.__version__, "distributed": distributed.__version__,
            "platform": platform.platform()}


# ---------------------------------------------------------------- the command

def _fail_on(text: str) -> list[str]:
    if text.strip().lower() == "none":
        return []
    wanted = [w.strip() for w in text.split(",") if w.strip()]
    unknown = [w for w in wanted if w not in FAIL_ON_CHOICES]
    if unknown:
        raise TrialsError(f"--fail-on: unknown {', '.join(unknown)} (choose from {', '.join(FAIL_ON_CHOICES)}, or none)")
    return wanted


def add_trials_parser(sub) -> None:
    p = sub.add_parser(
        "trials", help="a benchmark: many missions on many arenas, in parallel (dask)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run every arena of ARENAS_DIR (*.toml, e.g. from `rovernav arenas`) with each strategy and "
                    "seeds 1..K in the simulator, in parallel on dask.distributed (a local cluster by default), "
                    "and write trials.csv, trials.json, trials.md (headline, per family, per difficulty band), "
                    "runs/<strategy>/<arena>-s<seed>/{report.json,summary.png} and a gallery of the failed runs "
                    "(gallery/, gallery.md).",
        epilog="""\
per run:
  success         every leg reached with no contact (reached, 0 collisions, not crashed)
  'unreachable'   the host's no-path verdict: correct on an unsolvable arena, false on a
                  solvable one (solvable: the arena's [generated] label, else whether the
                  clairvoyant planner, every obstacle known, finds a path)
  OT, AT          optimal time (clairvoyant path length at the rover's cruise speed), mission time
  BARN score      success x OT / clip(AT, 4 OT, 8 OT)  (Xiao et al., 2022; at most 0.25)
  time score      success x OT / max(AT, OT)  (1 at the clairvoyant optimum)

exit status: 0 when the gate passes, 1 when a run of the rovernav strategy (the seed strategy is
a baseline) does something --fail-on names, 2 for bad input (no folder, no arenas, bad flag,
no scheduler), 3 an internal error (rerun with -v for the traceback), 130 interrupted.
--fail-on categories: crash, false_unreachable, timeout (the simulated
--max-time, or hung past --run-timeout), error (the run raised), failure (any failed run).

CI: rovernav trials ARENAS --sample 20 --strategy rovernav --seeds 1 --workers 2 --out out/trials""")
    p.add_argument("arenas_dir", type=Path, metavar="ARENAS_DIR", help="a folder of arena files (*.toml)")
    p.add_argument("--strategy", choices=("rovernav", "seed", "both"), default="rovernav",
                   help="which strategy to run (default rovernav)")
    p.add_argument("--seeds", type=number(1, 1000, integer=True), default=1, metavar="K",
                   help="simulator seeds 1..K per arena, K from 1 to 1000 (default 1)")
    p.add_argument("--sample", type=number(1, 100_000, integer=True), metavar="K",
                   help="only K arenas, a fixed choice: the families take turns for one more arena each "
                        "until K are chosen, and each family's arenas are taken evenly spaced through their "
                        "sorted names (positions floor(i*n/k))")
    p.add_argument("--out", type=out_dir, default=Path("out/trials"), metavar="DIR", help="output folder (default out/trials)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=number(0, 256, integer=True), default=os.cpu_count() or 1, metavar="N",
                       help="local dask worker processes (default: one per CPU, here %(default)s); 0 = --serial")
    where.add_argument("--serial", action="store_true", help="run in this process, one run after another (no dask)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the dask cluster at ADDRESS (e.g. tcp://10.0.0.5:8786); its workers must see "
                            "ARENAS_DIR and --out at the same paths")
    p.add_argument("--max-time", type=seconds(MAX_SIM_TIME_S, positive=True), default=DEFAULT_MAX_TIME_S, metavar="S",
                   help=f"simulated seconds before a run is stopped as a timeout (default {DEFAULT_MAX_TIME_S:g})")
    p.add_argument("--run-timeout", type=seconds(MAX_SIM_TIME_S, positive=True), default=DEFAULT_RUN_TIMEOUT_S, metavar="S",
                   help=f"wall-clock seconds before a run is stopped as hung (default {DEFAULT_RUN_TIMEOUT_S:g})")
    p.add_argument("--fail-on", default=",".join(DEFAULT_FAIL_ON), metavar="LIST",
                   help=f"what fails the gate, comma-separated from {', '.join(FAIL_ON_CHOICES)}, or none "
                        f"(default {','.join(DEFAULT_FAIL_ON)})")
    from ..sim.cli import add_radio_flags

    add_radio_flags(p, config=False)   # every run's radio; trials.json's settings.radio says what it was
    p.set_defaults(func=cmd_trials)


def radio_text(st: dict | None) -> str:
    """The radio's settings in a few words (trials.md)."""
    if not st:
        return "the simulator's default"
    parts = [f"{st['baud']:,} baud", f"{st['delay_ms']:g} ms latency", f"byte loss {st['loss_pct']:g} %",
             f"bit errors {st['ber_pct']:g} % of bytes"]
    burst = st["burst"]
    parts.append(f"in bursts of {burst['mean_s']:g} s mean, {100 * burst['share']:g} % of the time, one process "
                 "both ways" if burst else "independent, no bursts")
    parts.append(f"jitter {st['jitter_ms']:g} ms mean per frame" if st["jitter_ms"] else "no jitter")
    parts.append("half duplex (collisions)" if st["half_duplex"] else "full duplex")
    return ", ".join(parts)


def _command_line(args: argparse.Namespace, runner_flag: str) -> str:
    parts = ["rovernav", "trials", str(args.arenas_dir), "--strategy", args.strategy, "--seeds", str(args.seeds)]
    if args.sample is not None:
        parts += ["--sample", str(args.sample)]
    parts += ["--out", str(args.out), *runner_flag.split(), "--max-time", f"{args.max_time:g}",
              "--run-timeout", f"{args.run_timeout:g}", "--fail-on", args.fail_on]
    for flag, value in (("--radio-loss", args.radio_loss), ("--radio-ber", args.radio_ber),
                        ("--radio-jitter-ms", args.radio_jitter_ms)):
        if value is not None:
            parts += [flag, f"{value:g}"]
    if args.radio_burst is not None:
        parts += ["--radio-burst", f"{args.radio_burst[0]:g}:{args.radio_burst[1]:g}" if args.radio_burst[1] else "off"]
    if args.radio_half_duplex is not None:
        parts.append("--radio-half-duplex" if args.radio_half_duplex else "--no-radio-half-duplex")
    return " ".join(parts)


def _describe(row: dict) -> str:
    outcome = row["outcome"]
    if outcome in ("error", "hung") and row["mission_time_s"] is None:
        return f"{outcome}: {row['error']}"
    text = f"{outcome} {row['mission_time_s']:.1f} s"
    if row["crash_against"]:
        text += f" (into {row['crash_against']})"
    elif row["collisions"]:
        text += f" ({row['collisions']} contacts)"
    return text


def cmd_trials(args: argparse.Namespace) -> int:
    if args.seeds <= 0:
        raise TrialsError(f"--seeds must be >= 1, got {args.seeds}")
    if args.sample is not None and args.sample <= 0:
        raise TrialsError(f"--sample must be >= 1, got {args.sample}")
    if args.workers < 0:
        raise TrialsError(f"--workers must be >= 0, got {args.workers}")
    if args.max_time <= 0 or args.run_timeout <= 0:
        raise TrialsError("--max-time and --run-timeout must be > 0")
    fail_on = _fail_on(args.fail_on)
    from ..sim.channel import ChannelConfig, radio_config
    from ..sim.cli import radio_values

    values, names = radio_values(args)
    channel = radio_config(**values, names=names)   # refused here (one line, exit 2), before any run
    radio = None if channel == ChannelConfig() else values   # as given: each run makes the same ChannelConfig
    arenas = find_arenas(args.arenas_dir)
    if args.sample is not None:
        arenas = sample_arenas(arenas, args.sample)
    strategies = list(STRATEGIES) if args.strategy == "both" else [args.strategy]
    jobs = make_jobs(arenas, strategies, range(1, args.seeds + 1), args.out, args.max_time, args.run_timeout, radio)
    workers = 0 if args.serial else args.workers
    if args.scheduler:
        runner, runner_flag = f"the dask cluster at {args.scheduler}", f"--scheduler {args.scheduler}"
    elif workers == 0:
        runner, runner_flag = "serial, in one process", "--serial"
    else:
        runner, runner_flag = f"a local dask cluster of {workers} worker processes", f"--workers {workers}"
    args.out.mkdir(parents=True, exist_ok=True)

    def start() -> None:
        print(f"trials: {len(arenas)} arenas x {len(strategies)} strategies x {args.seeds} seeds = {len(jobs)} runs, "
              f"{runner}", flush=True)

    tally: dict[str, list[int]] = {s: [0, 0] for s in strategies}   # strategy -> [ok, done]

    def progress(done: int, total: int, row: dict) -> None:
        counts = tally[row["strategy"]]
        counts[0] += not row["failed"]
        counts[1] += 1
        so_far = ", ".join(f"{s} {ok}/{n} ok" for s, (ok, n) in tally.items())
        print(f"[{done}/{total}] {row['arena']} {row['strategy']} s{row['seed']}: {_describe(row)}   ({so_far})",
              flush=True)

    started_utc = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    started = time.monotonic()
    rows = run_jobs(jobs, workers, args.scheduler, start, progress)
    wall_time_s = time.monotonic() - started
    out = args.out.resolve()
    for row in rows:
        if row["report"]:
            row["report"] = os.path.relpath(row["report"], out)
    context = {
        "command": _command_line(args, runner_flag), "versions": versions(), "started_utc": started_utc,
        "wall_time_s": round(wall_time_s, 1),
        "settings": {"arenas_dir": str(args.arenas_dir), "arenas": len(arenas), "sample": args.sample,
                     "strategies": strategies, "seeds": list(range(1, args.seeds + 1)), "max_time_s": args.max_time,
                     "run_timeout_s": args.run_timeout, "runner": runner, "radio": channel.settings()}}
    summary = write_outputs(args.out, rows, context, fail_on)
    print()
    print(markdown_table("strategy", summary["headline"]))
    failed = sum(r["failed"] for r in rows)
    print(f"\nwrote {args.out}/trials.csv, trials.json, trials.md, runs/; {failed} failed runs in "
          f"{args.out}/gallery.md; {wall_time_s:.0f} s wall")
    gate = summary["gate"]
    if gate["passed"]:
        print(f"gate passed ({GATED_STRATEGY} runs; fail on {', '.join(fail_on) or 'nothing'})")
        return 0
    print(f"gate FAILED: {len(gate['violations'])} violations ({GATED_STRATEGY} runs):", file=sys.stderr)
    for v in gate["violations"][:20]:
        print(f"  {v['run']}: {v['category']} ({v['reason']})", file=sys.stderr)
    if len(gate["violations"]) > 20:
        print(f"  ... and {len(gate['violations']) - 20} more in trials.json", file=sys.stderr)
    return 1
