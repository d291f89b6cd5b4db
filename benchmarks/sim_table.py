"""The shared-scenario table of docs/results.md: every shared scenario, both strategies, several seeds, in the simulator.

    python benchmarks/sim_table.py [--seeds 1 2 3] [--jobs 2] [--json FILE]

For each scenario and strategy it prints the median mission time, the median path length against
the clairvoyant optimum (A* with every obstacle known), the median SPL, the replans, and how many
seeds reached the goal with zero collisions, as a Markdown table. Runs headless (no video).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

SCENARIOS = ["seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles", "out-and-back"]
STRATEGIES = ["rovernav", "seed"]


def run_one(scenario: str, strategy: str, seed: int) -> dict:
    from rovernav.evaluation.report import build_report
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    started = time.monotonic()
    sim = Simulation(load_scenario(scenario), SimOptions(seed=seed, strategy=strategy, max_time_s=1500))
    sim.run()
    report = build_report(sim, time.monotonic() - started)
    report.pop("events")
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenarios", nargs="+", default=SCENARIOS)
    ap.add_argument("--strategies", nargs="+", default=STRATEGIES)
    ap.add_argument("--json", type=Path, help="write every run's report here")
    args = ap.parse_args(argv)
    jobs = [(sc, st, seed) for sc in args.scenarios for st in args.strategies for seed in args.seeds]
    results: dict[tuple, list[dict]] = {}
    t0 = time.monotonic()
    from rovernav.evaluation.pool import map_runs

    for n, ((sc, st, seed), r) in enumerate(map_runs(run_one, jobs, args.jobs, ordered=False, star=True), 1):
        results.setdefault((sc, st), []).append(r)
        print(
            f"[{n}/{len(jobs)} {time.monotonic() - t0:5.0f} s] {sc} / {st} / seed {seed}: "
            f"{'reached' if r['reached'] else 'NOT reached'}, {r['mission_time_s']:.1f} s, "
            f"{r['collisions']} collisions, {r['speedup']}x",
            file=sys.stderr,
            flush=True,
        )
    med = statistics.median
    print(
        "| scenario | strategy | reached, 0 collisions | mission time (s) | path (m) | optimum (m) | SPL | replans | min clearance (m) | speed-up |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for sc in args.scenarios:
        for st in args.strategies:
            rs = results[(sc, st)]
            ok = sum(1 for r in rs if r["reached"] and r["collisions"] == 0)
            print(
                f"| {sc} | {st} | {ok}/{len(rs)} | {med(r['mission_time_s'] for r in rs):.1f} | "
                f"{med(r['path_length_m'] for r in rs):.2f} | {rs[0]['optimal_length_m']:.2f} | "
                f"{med(r['spl'] for r in rs):.2f} | {med(r['replans'] for r in rs):g} | "
                f"{min(r['min_clearance_m'] for r in rs):.3f} | {med(r['speedup'] for r in rs):.0f}x |"
            )
    print(
        f"\nmedians over seeds {', '.join(map(str, args.seeds))}; min clearance is the worst seed's; "
        f"{time.monotonic() - t0:.0f} s wall on {args.jobs} processes",
        file=sys.stderr,
    )
    if args.json:
        args.json.write_text(json.dumps({f"{k[0]}/{k[1]}": v for k, v in results.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
