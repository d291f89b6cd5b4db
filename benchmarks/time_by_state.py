"""Where a mission's time goes: the rover's simulated time in each of its states, summed over arenas.

    python benchmarks/time_by_state.py ARENAS_DIR [--every 10] [--seed 1] [--jobs 2] [--json FILE]

Runs every `--every`-th arena file of ARENAS_DIR (sorted by name; e.g. `rovernav arenas --count
200 --seed 1 --out A`) once with the rovernav strategy on the native core and sums the time the
rover spent in each state (DRIVE, SCAN, ROTATE, ...), read from the simulator's samples. It
prints a table of seconds and shares, the figure issue 28 (faster missions) starts from: how much
of a mission is stopped sweeps, turns and waits rather than driving.

A second table splits the sweeps by what began them, read from the rover's EVENTs stamped in the
step the sweep began and the state it left:
- reflex: the forward reflex stopped the rover (a REFLEX event);
- before a turn: a waypoint reached where the next leg turns sharply (a WAYPOINT_REACHED event);
- every 0.3 m: from DRIVE with neither (the distance since the last sweep);
- other: from any other state (a mission's start, a new path after a reflex stop, the radio back,
  a wait for the host's word that ran out).
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import time
from pathlib import Path


def run(args: tuple[str, int]) -> dict:
    from rovernav.link import messages_gen as mg
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    path, seed = args
    sim = Simulation(load_scenario(path), SimOptions(seed=seed, max_time_s=300))
    sim.run()
    spent: dict[str, float] = collections.Counter()
    for a, b in zip(sim.samples, sim.samples[1:]):
        spent[mg.RoverState(a.state).name] += b.t_s - a.t_s
    return {
        "arena": Path(path).stem,
        "outcome": sim.outcome,
        "mission_s": round(sim.t, 2),
        "states_s": {k: round(v, 3) for k, v in spent.items()},
        "sweeps": sweep_causes(sim.samples, [m for _, m in sim.mission.events]),
    }


def sweep_causes(samples, events) -> dict[str, list[float]]:
    """Each sweep's length [s], by what began it (see the module's doc): cause -> durations."""
    from rovernav.link import messages_gen as mg

    scan = mg.RoverState.SCAN
    near_ms = 15  # the sweep begins in the step of its cause; samples come every 10 ms
    causes: dict[str, list[float]] = collections.defaultdict(list)
    i = 1
    while i < len(samples):
        if samples[i].state == scan and samples[i - 1].state != scan:
            start = samples[i].t_s
            j = i
            while j < len(samples) and samples[j].state == scan:
                j += 1
            end = samples[j].t_s if j < len(samples) else samples[-1].t_s
            kinds = {e.kind for e in events if abs(e.time_ms - start * 1000.0) <= near_ms}
            if mg.EventKind.REFLEX in kinds:
                cause = "reflex"
            elif mg.EventKind.WAYPOINT_REACHED in kinds:
                cause = "before a turn"
            elif samples[i - 1].state == mg.RoverState.DRIVE:
                cause = "every 0.3 m"
            else:
                cause = "other"
            causes[cause].append(round(end - start, 3))
            i = j
        else:
            i += 1
    return dict(causes)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("arenas", help="a folder of arena files (*.toml)")
    ap.add_argument("--every", type=int, default=10, help="run every K-th arena (default 10)")
    ap.add_argument("--seed", type=int, default=1, help="the simulator's seed (default 1)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", help="write each run's figures here")
    a = ap.parse_args()
    files = sorted(Path(a.arenas).glob("*.toml"))
    if not files:
        ap.error(f"no arena files (*.toml) in {a.arenas}")
    if a.every < 1:
        ap.error("--every must be 1 or more")
    files = files[:: a.every]
    t0 = time.monotonic()
    results = []
    from rovernav.evaluation.pool import map_runs

    for n, (_, r) in enumerate(map_runs(run, [(str(f), a.seed) for f in files], a.jobs), 1):
        results.append(r)
        print(f"  {n}/{len(files)} {r['arena']}: {r['outcome']} {r['mission_s']:.1f} s", file=sys.stderr, flush=True)
    total: dict[str, float] = collections.Counter()
    for r in results:
        total.update(r["states_s"])
    whole = sum(total.values())
    print(
        f"\n{len(results)} runs of {a.arenas} (every {a.every}th, seed {a.seed}), "
        f"{whole:.0f} s simulated, {time.monotonic() - t0:.0f} s wall, {a.jobs} processes\n"
    )
    print("| state | time (s) | share |\n|---|---|---|")
    for state, s in sorted(total.items(), key=lambda kv: -kv[1]):
        print(f"| {state} | {s:.1f} | {100 * s / whole:.1f} % |")
    sweeps: dict[str, list[float]] = collections.defaultdict(list)
    for r in results:
        for cause, durations in r["sweeps"].items():
            sweeps[cause].extend(durations)
    n_sweeps = sum(len(d) for d in sweeps.values())
    if n_sweeps:
        scan_s = sum(sum(d) for d in sweeps.values())
        print(f"\n{n_sweeps} sweeps, {scan_s:.1f} s; by what began them:\n")
        print("| began by | sweeps | time (s) | share of sweep time | mean (s) |\n|---|---|---|---|---|")
        for cause, d in sorted(sweeps.items(), key=lambda kv: -sum(kv[1])):
            print(f"| {cause} | {len(d)} | {sum(d):.1f} | {100 * sum(d) / scan_s:.1f} % | {sum(d) / len(d):.2f} |")
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
