"""The Uno table of docs/uno.md: each shared scenario run by the native core and by the Uno image.

    python benchmarks/uno_table.py [--seeds 1 2 3] [--jobs 2] [--json FILE]
    python benchmarks/uno_table.py --arenas DIR [--sample K] --seeds 1     # arenas nobody tuned for

Besides the shared scenarios it runs the rover's own detours (the host's replanning off, as
`rovernav sim SCENARIO --no-host-replan`): Figure 4.8, and a wall and a row of posts that fill all
nine of the rover's obstacle disks in one sweep (scenarios/full-echoes-*.toml), the detour
planner's worst case (`--no-detours` leaves them out).

The Uno image (build/uno/firmware.elf, built if missing) runs in simavr with the simulated world on
its pins (`rovernav sim SCENARIO --rover uno`). For each scenario, over the seeds, it prints both
outcomes, the median mission times and their difference, and the image's own step times measured
in AVR cycles (the largest median, p99 and worst step of any seed, with what the worst step did),
the period's jitter and the stack's use and margin. It exits 1 if any seed's outcomes differ, a
step passes 5 ms, the jitter 1 ms, or the stack margin falls under 256 bytes: the figures issue
12 asks of the image. One seed's mission time swings by a few seconds with any change to the
rover (the runs are chaotic), hence the median over seeds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ["seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles", "out-and-back"]
# The rover alone: its own detour planner, the obstacle list full on the last two.
DETOURS = [
    "seed-fig4-8-unknown-obstacle",
    str(ROOT / "scenarios" / "full-echoes-wall.toml"),
    str(ROOT / "scenarios" / "full-echoes-posts.toml"),
]
ALONE = " (rover alone)"
STEP_LIMIT_US = 5000.0
JITTER_LIMIT_MS = 1.0
STACK_MARGIN_MIN = 256


def run_one(scenario: str, rover: str, seed: int) -> dict:
    from rovernav.evaluation.report import build_report
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    started = time.monotonic()
    alone = scenario.endswith(ALONE)
    name = scenario[: -len(ALONE)] if alone else scenario
    sim = Simulation(load_scenario(name), SimOptions(seed=seed, rover=rover, max_time_s=1500, host_replan=not alone))
    sim.run()
    report = build_report(sim, time.monotonic() - started)
    report.pop("events", None)
    if rover == "uno":
        report["uno_timing"] = sim.uno_timing()
    return report


def outcome(r: dict) -> str:
    """One run, as the progress lines show it: reached or not, its collisions, its mission time."""
    return f"{'reached' if r['reached'] else 'NOT reached'}, {r['collisions']} collisions, {r['mission_time_s']:.1f} s"


def _median_time_s(runs: list[dict]) -> float | None:
    """The median mission time [s] of the runs that reached (None: none did)."""
    times_s = [r["mission_time_s"] for r in runs if r["reached"] and r["mission_time_s"] is not None]
    return statistics.median(times_s) if times_s else None


def runs_cell(runs: list[dict]) -> str:
    """One column of the table: the runs that reached, the collisions of all of them (their sum,
    as each run's report counts them), and the median mission time of those that reached."""
    reached = sum(1 for r in runs if r["reached"])
    collisions = sum(r["collisions"] for r in runs)
    t_s = _median_time_s(runs)
    return f"{reached}/{len(runs)} reached, {collisions} collisions, {'no time' if t_s is None else f'{t_s:.1f} s'}"


def label_of(scenario: str) -> str:
    """The scenario's name in the table: its file's stem, and whether the rover was alone."""
    return Path(scenario[: -len(ALONE)]).stem + ALONE if scenario.endswith(ALONE) else Path(scenario).stem


def table_row(scenario: str, native: list[dict], uno: list[dict]) -> str:
    """The table's row for one scenario: the native core's runs and the Uno image's (one per seed,
    each a report as run_one returns it), and the image's step times, jitter and stack."""
    timing = [r["uno_timing"] for r in uno]
    worst = max((t["worst_step"] for t in timing), key=lambda w: w["us"])
    jitter_ms = max(t["period_jitter"]["max_abs_us"] for t in timing) / 1000
    used_bytes = max(t["stack"]["used_bytes"] for t in timing)
    margin_bytes = min(t["stack"]["margin_bytes"] for t in timing)
    t_nat_s, t_uno_s = _median_time_s(native), _median_time_s(uno)
    dt = f" ({100 * (t_uno_s - t_nat_s) / t_nat_s:+.1f} %)" if t_nat_s and t_uno_s else ""
    did = ", ".join(worst["flags"] or []) or "nothing flagged"
    return (
        f"| {label_of(scenario)} | {runs_cell(native)} | {runs_cell(uno)}{dt} | "
        f"{max(t['step_time']['median_us'] for t in timing) / 1000:.2f} / "
        f"{max(t['step_time']['p99_us'] for t in timing) / 1000:.2f} / {worst['us'] / 1000:.2f} ms "
        f"({worst['state']}: {did}) | {jitter_ms:.2f} ms | {used_bytes} / {margin_bytes} B |"
    )


def failures_of(scenario: str, seeds: list[int], native: list[dict], uno: list[dict]) -> list[str]:
    """What fails the benchmark for one scenario: a seed whose outcomes differ, a step past
    STEP_LIMIT_US, jitter past JITTER_LIMIT_MS, a stack margin under STACK_MARGIN_MIN."""
    timing = [r["uno_timing"] for r in uno]
    worst_us = max(t["worst_step"]["us"] for t in timing)
    jitter_ms = max(t["period_jitter"]["max_abs_us"] for t in timing) / 1000
    margin_bytes = min(t["stack"]["margin_bytes"] for t in timing)
    failures = []
    for seed, a, b in zip(seeds, native, uno):
        if (a["reached"], a["collisions"]) != (b["reached"], b["collisions"]):
            failures.append(f"{scenario} seed {seed}: outcomes differ (native {outcome(a)}; Uno image {outcome(b)})")
    if worst_us > STEP_LIMIT_US:
        failures.append(f"{scenario}: worst step {worst_us / 1000:.2f} ms > {STEP_LIMIT_US / 1000:g} ms")
    if jitter_ms > JITTER_LIMIT_MS:
        failures.append(f"{scenario}: jitter {jitter_ms:.2f} ms > {JITTER_LIMIT_MS:g} ms")
    if margin_bytes < STACK_MARGIN_MIN:
        failures.append(f"{scenario}: stack margin {margin_bytes} B < {STACK_MARGIN_MIN} B")
    return failures


TABLE_HEADER = (
    "| scenario | native | Uno image | Uno step: median / p99 / worst (what the worst did) | jitter "
    "| stack used / spare |\n|---|---|---|---|---|---|"
)


def table(scenarios: list[str], seeds: list[int], results: dict[tuple, dict]) -> tuple[str, list[str]]:
    """The whole table (Markdown) and what fails, from every run's report keyed (scenario, rover, seed)."""
    rows, failures = [TABLE_HEADER], []
    for sc in scenarios:
        native = [results[(sc, "native", s)] for s in seeds]
        uno = [results[(sc, "uno", s)] for s in seeds]
        rows.append(table_row(sc, native, uno))
        failures += failures_of(sc, seeds, native, uno)
    return "\n".join(rows), failures


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenarios", nargs="+", default=SCENARIOS, help="names or files (default: the four shared)")
    ap.add_argument("--arenas", type=Path, help="instead, the arena files (*.toml) of this folder (`rovernav arenas`)")
    ap.add_argument("--sample", type=int, help="with --arenas: only K of them, evenly spaced in name order")
    ap.add_argument("--no-detours", action="store_true", help="leave out the rover-alone detours")
    ap.add_argument("--json", type=Path, help="write every run's report here")
    args = ap.parse_args(argv)
    if args.arenas is None and not args.no_detours:
        args.scenarios = list(args.scenarios) + [d + ALONE for d in DETOURS]
    if args.arenas is not None:
        files = sorted(args.arenas.glob("*.toml"))
        if not files:
            ap.error(f"--arenas {args.arenas}: no *.toml arena files there")
        if args.sample:
            files = [files[i * len(files) // args.sample] for i in range(min(args.sample, len(files)))]
        args.scenarios = [str(f) for f in files]
    jobs = [(sc, rover, seed) for sc in args.scenarios for seed in args.seeds for rover in ("uno", "native")]
    results: dict[tuple, dict] = {}
    t0 = time.monotonic()
    from rovernav.evaluation.pool import map_runs

    for n, (job, r) in enumerate(map_runs(run_one, jobs, args.jobs, ordered=False, star=True), 1):
        sc, rover, seed = job
        results[(sc, rover, seed)] = r
        print(
            f"[{n}/{len(jobs)} {time.monotonic() - t0:5.0f} s] {sc} / {rover} / seed {seed}: {outcome(r)}",
            file=sys.stderr,
            flush=True,
        )
    text, failures = table(args.scenarios, args.seeds, results)
    print(text)
    print(f"\n({time.monotonic() - t0:.0f} s for {len(jobs)} runs, {args.jobs} at a time)")
    if args.json:
        args.json.write_text(json.dumps({f"{sc}/{rv}/{seed}": r for (sc, rv, seed), r in results.items()}, indent=1))
    for f in failures:
        print("FAIL:", f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
