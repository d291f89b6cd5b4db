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

The --radio-* flags set every run's simulated radio as they do `rovernav sim`'s (rovernav/radio.py, modelled by sim/channel.py);
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
(the traceback in its folder's error.txt) and the others go on."""

from __future__ import annotations

import argparse
import datetime
import functools
import os
import sys
import time
from pathlib import Path

from ..sim.camera_process import spare_core
from ..validate import MAX_SIM_TIME_S, number, out_dir, seconds
from .jobs import TrialJob, TrialsError, failure_row, find_arenas, make_jobs, run_trial, sample_arenas
from .pool import HANG_GRACE_S, POLL_S, run_jobs
from .scoring import (
    BARN_CLIP_HIGH,
    BARN_CLIP_LOW,
    GATED_STRATEGY,
    ROW_FIELDS,
    STRATEGIES,
    UNLABELLED,
    barn_score,
    derive,
    failure_reason,
    gate_violations,
    headline,
    headlines_by,
    row_from_report,
    strategies_of,
    time_score,
)
from .tables import (
    DEFINITIONS,
    TABLE_COLUMNS,
    markdown_table,
    radio_text,
    render_markdown,
    versions,
    write_gallery,
    write_outputs,
)

# The public names of the command's parts (jobs, scoring, pool, tables) are importable from here too,
# as they were from rovernav.sim.trials.
__all__ = [
    "STRATEGIES",
    "GATED_STRATEGY",
    "FAIL_ON_CHOICES",
    "DEFAULT_FAIL_ON",
    "DEFAULT_MAX_TIME_S",
    "DEFAULT_RUN_TIMEOUT_S",
    "HANG_GRACE_S",
    "POLL_S",
    "UNLABELLED",
    "BARN_CLIP_LOW",
    "BARN_CLIP_HIGH",
    "ROW_FIELDS",
    "TrialsError",
    "TrialJob",
    "find_arenas",
    "sample_arenas",
    "make_jobs",
    "run_trial",
    "row_from_report",
    "failure_row",
    "barn_score",
    "time_score",
    "derive",
    "failure_reason",
    "run_jobs",
    "headline",
    "strategies_of",
    "headlines_by",
    "gate_violations",
    "TABLE_COLUMNS",
    "markdown_table",
    "DEFINITIONS",
    "render_markdown",
    "write_gallery",
    "write_outputs",
    "versions",
    "add_trials_parser",
    "radio_text",
    "cmd_trials",
]


FAIL_ON_CHOICES = ("crash", "false_unreachable", "timeout", "error", "failure")
DEFAULT_FAIL_ON = ("crash", "false_unreachable", "timeout", "error")
DEFAULT_MAX_TIME_S = 300.0
DEFAULT_RUN_TIMEOUT_S = 600.0


# ---------------------------------------------------------------- the command


def _fail_on(text: str) -> list[str]:
    if text.strip().lower() == "none":
        return []
    wanted = [w.strip() for w in text.split(",") if w.strip()]
    unknown = [w for w in wanted if w not in FAIL_ON_CHOICES]
    if unknown:
        raise TrialsError(
            f"--fail-on: unknown {', '.join(unknown)} (choose from {', '.join(FAIL_ON_CHOICES)}, or none)"
        )
    return wanted


def add_trials_parser(sub) -> None:
    p = sub.add_parser(
        "trials",
        help="a benchmark: many missions on many arenas, in parallel (dask)",
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

CI: rovernav trials ARENAS --sample 20 --strategy rovernav --seeds 1 --workers 2 --out out/trials""",
    )
    p.add_argument("arenas_dir", type=Path, metavar="ARENAS_DIR", help="a folder of arena files (*.toml)")
    p.add_argument(
        "--strategy",
        choices=("rovernav", "seed", "both"),
        default="rovernav",
        help="which strategy to run (default rovernav)",
    )
    p.add_argument(
        "--seeds",
        type=number(1, 1000, integer=True),
        default=1,
        metavar="K",
        help="simulator seeds 1..K per arena, K from 1 to 1000 (default 1)",
    )
    p.add_argument(
        "--sample",
        type=number(1, 100_000, integer=True),
        metavar="K",
        help="only K arenas, a fixed choice: the families take turns for one more arena each "
        "until K are chosen, and each family's arenas are taken evenly spaced through their "
        "sorted names (positions floor(i*n/k))",
    )
    p.add_argument(
        "--out", type=out_dir, default=Path("out/trials"), metavar="DIR", help="output folder (default out/trials)"
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=number(0, 256, integer=True),
        default=os.cpu_count() or 1,
        metavar="N",
        help="local dask worker processes (default: one per CPU, here %(default)s); 0 = --serial",
    )
    where.add_argument(
        "--serial",
        action="store_true",
        help="run in this process, one run after another (no dask); on a machine with two cores or more "
        "each run renders and locates its frames in a second process (sim/camera_process.py)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="use the dask cluster at ADDRESS (e.g. tcp://10.0.0.5:8786); its workers must see "
        "ARENAS_DIR and --out at the same paths",
    )
    p.add_argument(
        "--max-time",
        type=seconds(MAX_SIM_TIME_S, positive=True),
        default=DEFAULT_MAX_TIME_S,
        metavar="S",
        help=f"simulated seconds before a run is stopped as a timeout (default {DEFAULT_MAX_TIME_S:g})",
    )
    p.add_argument(
        "--run-timeout",
        type=seconds(MAX_SIM_TIME_S, positive=True),
        default=DEFAULT_RUN_TIMEOUT_S,
        metavar="S",
        help=f"wall-clock seconds before a run is stopped as hung (default {DEFAULT_RUN_TIMEOUT_S:g})",
    )
    p.add_argument(
        "--fail-on",
        default=",".join(DEFAULT_FAIL_ON),
        metavar="LIST",
        help=f"what fails the gate, comma-separated from {', '.join(FAIL_ON_CHOICES)}, or none "
        f"(default {','.join(DEFAULT_FAIL_ON)})",
    )
    from ..config import MISSION_PLANNERS

    p.add_argument(
        "--planner",
        choices=MISSION_PLANNERS,
        default="astar",
        help="the host's global planner for every run, as [mission] planner sets it: astar (16 directions, "
        "the default) or theta (any angle, Theta*)",
    )
    p.add_argument(
        "--fix-hz",
        type=number(0.0, 120.0),
        default=0.0,
        metavar="HZ",
        help="the host sends at most HZ camera fixes a second, as [mission] fix_hz sets it (0, the "
        "default: one for every frame that sees the rover; else at least 6, three within the rover's "
        "fix_timeout_ms of 500 ms)",
    )
    from ..radio_flags import add_radio_flags

    add_radio_flags(p, config=False)  # every run's radio; trials.json's settings.radio says what it was
    p.set_defaults(func=cmd_trials)


def _command_line(args: argparse.Namespace, runner_flag: str) -> str:
    parts = ["rovernav", "trials", str(args.arenas_dir), "--strategy", args.strategy, "--seeds", str(args.seeds)]
    if args.sample is not None:
        parts += ["--sample", str(args.sample)]
    if getattr(args, "planner", "astar") != "astar":
        parts += ["--planner", args.planner]
    if getattr(args, "fix_hz", 0.0):
        parts += ["--fix-hz", f"{args.fix_hz:g}"]
    parts += [
        "--out",
        str(args.out),
        *runner_flag.split(),
        "--max-time",
        f"{args.max_time:g}",
        "--run-timeout",
        f"{args.run_timeout:g}",
        "--fail-on",
        args.fail_on,
    ]
    for flag, value in (
        ("--radio-loss", args.radio_loss),
        ("--radio-ber", args.radio_ber),
        ("--radio-jitter-ms", args.radio_jitter_ms),
    ):
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
    from ..config import MIN_FIX_HZ

    if 0.0 < args.fix_hz < MIN_FIX_HZ:
        raise TrialsError(
            f"--fix-hz {args.fix_hz:g}: 0 (a fix for every frame) or at least {MIN_FIX_HZ:g} (3 within the "
            "rover's fix_timeout_ms, 500 ms)"
        )
    if args.max_time <= 0 or args.run_timeout <= 0:
        raise TrialsError("--max-time and --run-timeout must be > 0")
    fail_on = _fail_on(args.fail_on)
    from ..radio import ChannelConfig, radio_config
    from ..radio_flags import radio_values

    values, names = radio_values(args)
    channel = radio_config(**values, names=names)  # refused here (one line, exit 2), before any run
    radio = None if channel == ChannelConfig() else values  # as given: each run makes the same ChannelConfig
    arenas = find_arenas(args.arenas_dir)
    if args.sample is not None:
        arenas = sample_arenas(arenas, args.sample)
    strategies = list(STRATEGIES) if args.strategy == "both" else [args.strategy]
    jobs = make_jobs(
        arenas,
        strategies,
        range(1, args.seeds + 1),
        args.out,
        args.max_time,
        args.run_timeout,
        radio,
        args.planner,
        args.fix_hz,
    )
    workers = 0 if args.serial else args.workers
    trial = run_trial
    if args.scheduler:
        runner, runner_flag = f"the dask cluster at {args.scheduler}", f"--scheduler {args.scheduler}"
    elif workers == 0:
        runner, runner_flag = "serial, in one process", "--serial"
        if spare_core():  # one run at a time: a second core renders and locates its frames
            runner += ", the camera on a second core"
            trial = functools.partial(run_trial, camera_process=True)
    else:
        runner, runner_flag = f"a local dask cluster of {workers} worker processes", f"--workers {workers}"
    args.out.mkdir(parents=True, exist_ok=True)

    def start() -> None:
        print(
            f"trials: {len(arenas)} arenas x {len(strategies)} strategies x {args.seeds} seeds = {len(jobs)} runs, "
            f"{runner}",
            flush=True,
        )

    tally: dict[str, list[int]] = {s: [0, 0] for s in strategies}  # strategy -> [ok, done]

    def progress(done: int, total: int, row: dict) -> None:
        counts = tally[row["strategy"]]
        counts[0] += not row["failed"]
        counts[1] += 1
        so_far = ", ".join(f"{s} {ok}/{n} ok" for s, (ok, n) in tally.items())
        print(
            f"[{done}/{total}] {row['arena']} {row['strategy']} s{row['seed']}: {_describe(row)}   ({so_far})",
            flush=True,
        )

    started_utc = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    started = time.monotonic()
    rows = run_jobs(jobs, workers, args.scheduler, start, progress, trial=trial)
    wall_time_s = time.monotonic() - started
    out = args.out.resolve()
    for row in rows:
        if row["report"]:
            row["report"] = os.path.relpath(row["report"], out)
    context = {
        "command": _command_line(args, runner_flag),
        "versions": versions(),
        "started_utc": started_utc,
        "wall_time_s": round(wall_time_s, 1),
        "settings": {
            "arenas_dir": str(args.arenas_dir),
            "arenas": len(arenas),
            "sample": args.sample,
            "strategies": strategies,
            "seeds": list(range(1, args.seeds + 1)),
            "max_time_s": args.max_time,
            "run_timeout_s": args.run_timeout,
            "runner": runner,
            "radio": channel.settings(),
            "planner": args.planner,
            "fix_hz": args.fix_hz,
        },
    }
    summary = write_outputs(args.out, rows, context, fail_on)
    print()
    print(markdown_table("strategy", summary["headline"]))
    failed = sum(r["failed"] for r in rows)
    print(
        f"\nwrote {args.out}/trials.csv, trials.json, trials.md, runs/; {failed} failed runs in "
        f"{args.out}/gallery.md; {wall_time_s:.0f} s wall"
    )
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
