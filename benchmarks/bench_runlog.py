#!/usr/bin/env python3
"""What the run log costs and holds: a simulated mission with and without its MCAP log.

    python benchmarks/bench_runlog.py [SCENARIO] [--runs N] [--seed S]

For each of N runs (default 3) of SCENARIO (default out-and-back), without video: the wall time
without a log, with the log (images at 2 Hz) and with the log but no images, the log's size
(MB, and kB per simulated minute), its messages per channel, and how long `rovernav replay`
takes to read it and run the host again (and that the replay is identical). Prints medians.

    python benchmarks/bench_runlog.py --arenas DIR [--sample 24] [--seed 7]

Replay on arenas nobody tuned for: K generated arenas (`rovernav arenas`), each with a random
simulator seed and a random fault (a radio outage, or a host restart) in its first 30 s; every
log is replayed and must give the recorded host's decisions exactly. Exits 1 if one does not.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from mcap.reader import make_reader  # noqa: E402

from rovernav.runlog.replay import read_log, replay  # noqa: E402
from rovernav.scenario import load_scenario  # noqa: E402
from rovernav.sim.runner import SimOptions, Simulation  # noqa: E402


def one(scenario, seed: int, log: Path | None, image_hz: float = 2.0) -> tuple[float, float]:
    sim = Simulation(scenario, SimOptions(seed=seed, log=log, log_image_hz=image_hz), progress=lambda t, x: None)
    started = time.perf_counter()
    sim.run()
    sim.close_log()
    return time.perf_counter() - started, sim.t


def arenas(folder: Path, sample: int, seed: int) -> int:
    import random

    from rovernav.sim.runner import Faults

    files = sorted(folder.glob("*.toml"))
    if not files:
        print(f"no arenas in {folder}: make them with rovernav arenas --out {folder}", file=sys.stderr)
        return 2
    rng = random.Random(seed)
    same, outcomes = 0, {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, path in enumerate(rng.sample(files, min(sample, len(files)))):
            sim_seed = rng.randint(1, 10**6)
            faults = (
                Faults(link_outages=[(rng.uniform(5, 30), rng.uniform(1, 8))])
                if i % 2
                else Faults(host_restarts=[rng.uniform(5, 30)])
            )
            log = Path(tmp) / f"{i}.mcap"
            sim = Simulation(
                load_scenario(path),
                SimOptions(seed=sim_seed, log=log, log_image_hz=0, faults=faults, max_time_s=300),
                progress=lambda t, x: None,
            )
            sim.run()
            sim.close_log()
            result = replay(read_log(log))
            same += result.identical
            outcomes[sim.outcome] = outcomes.get(sim.outcome, 0) + 1
            print(
                f"{path.stem} seed {sim_seed} {'outage' if i % 2 else 'host restart'}: {sim.outcome}, replay "
                f"{'identical' if result.identical else f'DIFFERENT at frame {result.first_difference()}'}",
                flush=True,
            )
    n = sum(outcomes.values())
    print(f"\n{same}/{n} replays identical; outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(outcomes.items())))
    return 0 if same == n else 1


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenario", nargs="?", default="out-and-back")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--seed", type=int, default=None, help="simulator seed (default 1); with --arenas, the draw's (7)")
    p.add_argument("--arenas", type=Path, help="replay logs of generated arenas in this folder instead")
    p.add_argument("--sample", type=int, default=24)
    args = p.parse_args()
    if args.arenas:
        return arenas(args.arenas, args.sample, 7 if args.seed is None else args.seed)
    args.seed = 1 if args.seed is None else args.seed
    sc = load_scenario(args.scenario)
    rows: dict[str, list[float]] = {k: [] for k in ("none", "log", "log_no_images", "read", "replay", "mb", "kb_min")}
    counts = {}
    identical = True
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "run.mcap"
        for k in range(args.runs):
            wall, _t = one(sc, args.seed, None)
            rows["none"].append(wall)
            wall, _t = one(sc, args.seed, Path(tmp) / "noimg.mcap", image_hz=0.0)
            rows["log_no_images"].append(wall)
            wall, t = one(sc, args.seed, log)
            rows["log"].append(wall)
            rows["mb"].append(log.stat().st_size / 1e6)
            rows["kb_min"].append(log.stat().st_size / 1e3 / (t / 60))
            started = time.perf_counter()
            run = read_log(log)
            rows["read"].append(time.perf_counter() - started)
            started = time.perf_counter()
            identical &= replay(run).identical
            rows["replay"].append(time.perf_counter() - started)
            print(
                f"run {k + 1}: {t:.1f} s simulated; wall {rows['none'][-1]:.2f} s without a log, "
                f"{rows['log_no_images'][-1]:.2f} s with (no images), {wall:.2f} s with (images at 2 Hz); "
                f"log {rows['mb'][-1]:.2f} MB",
                flush=True,
            )
        with open(log, "rb") as f:
            s = make_reader(f).get_summary()
            counts = {s.channels[c].topic: n for c, n in s.statistics.channel_message_counts.items()}
    med = {k: statistics.median(v) for k, v in rows.items()}
    print(f"\n{args.scenario}, seed {args.seed}, medians of {args.runs} runs (no video):")
    print(
        f"  wall time: {med['none']:.2f} s without a log, {med['log_no_images']:.2f} s with it and no images "
        f"(+{100 * (med['log_no_images'] / med['none'] - 1):.0f} %), {med['log']:.2f} s with images at 2 Hz "
        f"(+{100 * (med['log'] / med['none'] - 1):.0f} %)"
    )
    print(f"  log: {med['mb']:.2f} MB ({med['kb_min']:.0f} kB per simulated minute)")
    print(f"  replay: read {med['read']:.2f} s, host again {med['replay']:.2f} s; identical: {identical}")
    print("  messages per channel: " + ", ".join(f"{t} {n}" for t, n in sorted(counts.items())))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
