"""Randomised outage trials: the rover alone, on the shared scenarios.

    python benchmarks/outage_trials.py [--trials 100] [--jobs 2] [--seed 7] [--json FILE]

Each trial draws a scenario (the three one-leg seed arenas), a simulator seed, an outage kind
(the whole radio, or the camera), its start (3-25 s into the mission, when the rover is on its
way) and its length (2-30 s). It reports the completion rate, the collisions (which must be 0),
the dead-reckoning error the first fix after each outage revealed, how often the rover held
because its estimate grew too uncertain, and how long it took to recover.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

SCENARIOS = ["seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles"]


def trial(args: tuple) -> dict:
    scenario, seed, kind, start, length = args
    from rovernav.evaluation.report import fault_figures
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import Faults, SimOptions, Simulation

    faults = Faults(link_outages=[(start, length)]) if kind == "radio" else Faults(camera_outages=[(start, length)])
    sim = Simulation(load_scenario(scenario), SimOptions(seed=seed, faults=faults, max_time_s=400))
    sim.run()
    f = fault_figures(sim)
    return {
        "scenario": scenario,
        "seed": seed,
        "kind": kind,
        "start_s": start,
        "length_s": length,
        "reached": all(leg.reached for leg in sim.mission.legs) and len(sim.mission.legs) == sim.mission.legs_asked,
        "collisions": sim.collisions,
        "min_clearance_m": sim.min_clearance_m,
        "mission_time_s": sim.t,
        "dr_errors_m": f["dr_errors_m"],
        "holds": len(f["holds"]),
        "recoveries_s": f["hold_recovery_s"],
        "error": sim.mission.error,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--json", help="write every trial here")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    jobs = [
        (
            SCENARIOS[int(rng.integers(len(SCENARIOS)))],
            int(rng.integers(1, 10_000)),
            "radio" if rng.random() < 0.5 else "camera",
            round(float(rng.uniform(3, 25)), 1),
            round(float(rng.uniform(2, 30)), 1),
        )
        for _ in range(a.trials)
    ]
    t0 = time.monotonic()
    results = []
    from rovernav.evaluation.pool import map_runs

    for n, (_, r) in enumerate(map_runs(trial, jobs, a.jobs), 1):
        results.append(r)
        if n % 10 == 0:
            print(f"  {n}/{len(jobs)} trials, {time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
    reached = sum(r["reached"] for r in results)
    collisions = sum(r["collisions"] for r in results)
    errors = np.array([e for r in results for e in r["dr_errors_m"]]) * 1000
    holds = sum(r["holds"] for r in results)
    rec = [x for r in results for x in r["recoveries_s"] if x is not None]
    print(
        f"{len(results)} trials ({sum(r['kind'] == 'radio' for r in results)} radio, "
        f"{sum(r['kind'] == 'camera' for r in results)} camera outages of 2-30 s), {a.jobs} processes, "
        f"{time.monotonic() - t0:.0f} s"
    )
    print(f"completed: {reached}/{len(results)} ({100 * reached / len(results):.0f} %)")
    print(f"collisions: {collisions}")
    if len(errors):
        print(
            f"dead-reckoning error when fixes returned (mm), {len(errors)} outages: median {np.median(errors):.0f}, "
            f"90th percentile {np.percentile(errors, 90):.0f}, max {errors.max():.0f}"
        )
    print(
        f"safe stops (hold): {holds}; time to recover after a hold (s): "
        + (f"median {np.median(rec):.1f}, max {max(rec):.1f}" if rec else "none")
    )
    worst = min(r["min_clearance_m"] for r in results)
    print(f"closest any rover came to an obstacle: {worst * 1000:.0f} mm")
    failed = [r for r in results if not r["reached"] or r["collisions"]]
    for r in failed[:10]:
        print(
            f"  not completed: {r['scenario']} seed {r['seed']} {r['kind']} {r['start_s']}+{r['length_s']} s: "
            f"{r['error'] or 'timed out'}, {r['collisions']} collisions"
        )
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0 if collisions == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
