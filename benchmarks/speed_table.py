"""The README's speed figures in one command: the simulator, the planner and vision, each beside
the implementation before issue 29, measured in the same run.

    python benchmarks/speed_table.py [--quick]

Runs, one after another (each prints its own table on stderr as it goes):
- benchmarks/bench_sim_speed.py (3 runs: out-and-back as `rovernav sim` runs it, and 20
  generated arenas one after another in one process; beside the tree at 8c6a53c);
- benchmarks/bench_planning.py (21 runs a case, beside the previous A* and grid build, and scipy);
- benchmarks/bench_vision.py (3 runs of 300 frames, beside the previous colour-marker finder),
then prints the Markdown table the README copies, with the command for each line. --quick: one
run each and 4 arenas (a check that it works; its figures are not the README's). About 12 minutes
on this project's 2-core machine, most of it the simulator's; the machine should be otherwise idle.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _run(script: str, args: list[str], out: Path) -> dict:
    cmd = [sys.executable, str(HERE / script), *args, "--json", str(out)]
    print(f"$ {' '.join(cmd[1:])}", file=sys.stderr, flush=True)
    env = dict(os.environ, PYTHONPATH=str(HERE.parent / "host"))  # this tree's rovernav
    proc = subprocess.run(cmd, stdout=sys.stderr, env=env)
    if proc.returncode not in (0, 2) or not out.exists():  # bench_planning: 2 = a target missed
        raise SystemExit(f"speed_table: {script} failed (exit {proc.returncode})")
    return json.loads(out.read_text())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="one run each, 4 arenas: a check, not the figures")
    args = ap.parse_args(argv)
    runs = ["--runs", "1"] if args.quick else []
    with tempfile.TemporaryDirectory(prefix="rovernav-speed-") as where:
        tmp = Path(where)
        sim = _run("bench_sim_speed.py", runs + (["--arenas", "4"] if args.quick else []), tmp / "sim.json")
        planning = _run(
            "bench_planning.py", (["--runs", "3"] if args.quick else []) + ["--no-plain"], tmp / "plan.json"
        )
        vision = _run("bench_vision.py", (["--runs", "1", "--frames", "60"] if args.quick else []), tmp / "vision.json")

    lines = ["| what | now | before (same run) | goal | command |", "|---|---|---|---|---|"]
    ref = {r["missions"]: r["speedup"] for r in sim["rows"] if r["configuration"] == "reference"}
    for r in sim["rows"]:
        if r["configuration"] == "reference":
            continue
        before = f"{ref[r['missions']]:.1f}x" if r["missions"] in ref else "-"
        lines.append(
            f"| simulator, {r['missions']}, log on, {r['configuration']} | **{r['speedup']:.1f}x** real time | "
            f"{before} | 50x | `python benchmarks/bench_sim_speed.py` |"
        )
    for c in planning["cases"]:
        lines.append(
            f"| planner, {c['case']} ({c['cells']} cells), grid + A* | **{c['ours_ms']:.2f} ms** | "
            f"{c['previous_ms']:.2f} ms (scipy {c['scipy_ms']:.1f} ms) | {c['target_ms']:g} ms | "
            "`python benchmarks/bench_planning.py` |"
        )
    for r in vision["rows"]:
        if r.get("ref_ms_median") is None:
            continue
        lines.append(
            f"| vision, {r['kind']} markers, {r['mode']} | **{r['locate_ms_median']:.3f} ms** a frame | "
            f"{r['ref_ms_median']:.3f} ms | {'0.3 ms' if r['mode'] == 'tracking' else '-'} | "
            "`python benchmarks/bench_vision.py` |"
        )
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
