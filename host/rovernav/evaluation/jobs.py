"""The runs of a benchmark: the arenas (all, or a sample that covers the families), one job per
arena, strategy and seed, and one run in the simulator (run_trial)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterable
from pathlib import Path

from ..errors import InputError
from ..files import strict_json_value
from .scoring import UNLABELLED, _blank_row, derive, row_from_report


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
    radio: tuple = ()  # the simulated radio's settings, (name, value) pairs for radio_config (): defaults
    planner: str = "astar"  # the host's global planner ([mission] planner)
    fix_hz: float = 0.0  # the host's FIX rate ([mission] fix_hz; 0: every frame)

    @property
    def arena(self) -> str:
        return self.arena_path.stem

    @property
    def label(self) -> str:
        return f"{self.arena} {self.strategy} s{self.seed}"

    @property
    def args(self) -> tuple:
        """run_trial's arguments, plain values that pickle to any worker."""
        args = (str(self.arena_path), self.strategy, self.seed, str(self.run_dir), self.max_time_s, self.run_timeout_s)
        if self.fix_hz:
            return args + (dict(self.radio) or None, self.planner, self.fix_hz)
        if self.planner != "astar":
            return args + (dict(self.radio) or None, self.planner)
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
    families: dict[str, list[int]] = {}  # family -> positions in `arenas`
    for i, (_, meta) in enumerate(arenas):
        families.setdefault((meta or {}).get("family", UNLABELLED), []).append(i)
    quota = dict.fromkeys(families, 0)
    while sum(quota.values()) < min(count, len(arenas)):
        for name, members in families.items():
            if quota[name] < len(members) and sum(quota.values()) < count:
                quota[name] += 1
    chosen = sorted(i for name, members in families.items() for i in _evenly_spaced(members, quota[name]))
    return [arenas[i] for i in chosen]


def make_jobs(
    arenas: list[tuple[Path, dict | None]],
    strategies: Iterable[str],
    seeds: Iterable[int],
    out_dir: Path,
    max_time_s: float,
    run_timeout_s: float | None,
    radio: dict | None = None,
    planner: str = "astar",
    fix_hz: float = 0.0,
) -> list[TrialJob]:
    """One job per arena, strategy and seed; runs go to out_dir/runs/<strategy>/<arena>-s<seed>/.
    `radio`: radio_config's settings for the simulated radio (None: its defaults); `planner`: the
    host's global planner."""
    runs = Path(out_dir).resolve() / "runs"
    radio_items = tuple(sorted((radio or {}).items()))
    return [
        TrialJob(
            path.resolve(),
            strategy,
            seed,
            runs / strategy / f"{path.stem}-s{seed}",
            max_time_s,
            run_timeout_s,
            meta,
            radio_items,
            planner,
            fix_hz,
        )
        for path, meta in arenas
        for strategy in strategies
        for seed in seeds
    ]


# ---------------------------------------------------------------- one run


def _mission_config(planner: str, fix_hz: float = 0.0):
    """The default configuration with [mission] planner and fix_hz set."""
    from ..config import config_from_dict

    return config_from_dict({"mission": {"planner": planner, "fix_hz": float(fix_hz)}})


def run_trial(
    scenario_path: str,
    strategy: str,
    seed: int,
    out_dir: str,
    max_time_s: float,
    run_timeout_s: float | None = None,
    radio: dict | None = None,
    planner: str = "astar",
    fix_hz: float = 0.0,
    camera_process: bool = False,
) -> dict:
    """Simulate one mission headless and return its row (ROW_FIELDS).

    Writes out_dir/report.json (strict JSON) and out_dir/summary.png, each atomically. The
    mission stops at `max_time_s` simulated seconds (outcome "timeout"); past `run_timeout_s`
    seconds of wall time it stops at the simulator's next event or 30-second mark (outcome
    "hung", with the report so far). Safe in a dask worker process: it imports what it needs
    and keeps no state. Exceptions from the simulator propagate (the caller records an error).
    `radio`: the simulated radio's settings as radio_config takes them (None: the defaults).
    `planner`: the host's global planner ([mission] planner: "astar" or "theta").
    `fix_hz`: the host's FIX rate ([mission] fix_hz; 0: a FIX for every frame that sees the rover).
    `camera_process`: render and locate frames in a second process (sim/camera_process.py; the
    serial runner's, on a machine with a core to spare).
    """
    from ..radio import ChannelConfig, radio_config
    from ..scenario import load_scenario
    from ..sim.runner import SimOptions, Simulation
    from .report import build_report, summary_picture, write_report

    started = time.monotonic()
    deadline = None if run_timeout_s is None else started + run_timeout_s

    def guard(t_s: float, text: str | None) -> None:
        if deadline is not None and time.monotonic() > deadline:
            raise _WallClockExceeded(
                f"stopped after {run_timeout_s:g} s of wall time (--run-timeout) at {t_s:.1f} s simulated"
            )

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    channel = radio_config(**radio) if radio else ChannelConfig()
    sim = Simulation(
        load_scenario(scenario_path),
        SimOptions(
            seed=seed,
            strategy=strategy,
            max_time_s=max_time_s,
            channel=channel,
            config=None if planner == "astar" and not fix_hz else _mission_config(planner, fix_hz),
            camera_process=camera_process,
        ),
        progress=guard,
    )
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
    summary_picture(sim, report, out / "summary.png")  # written atomically
    row = row_from_report(report, Path(scenario_path).stem)
    row["wall_time_s"] = round(time.monotonic() - started, 2)
    row["report"] = str(out / "report.json")
    return row


def failure_row(job: TrialJob, outcome: str, error: str) -> dict:
    """The row of a run that left no report: it raised ("error") or never came back ("hung")."""
    row = _blank_row(job.arena, job.strategy, job.seed, job.meta)
    row.update(outcome=outcome, error=error)
    return derive(row)
