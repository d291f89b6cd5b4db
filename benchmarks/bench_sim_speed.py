"""How fast the simulator runs, as users run it: `rovernav sim SCENARIO --no-video` (the run log
on), against the previous implementation in the same run.

    python benchmarks/bench_sim_speed.py [--runs 3] [--arenas 20] [--reference REV | --reference none]
                                         [--json FILE]

Each configuration runs the same missions, interleaved run by run so that they share the
machine's state:
- `ours`: this tree, as `rovernav sim --no-video` runs by default (the camera in its own process
  on a machine with two usable cores: sim/camera_process.py);
- `ours, one core`: this tree with `--camera-process off` (everything in one process, as trials'
  workers run it);
- `reference`: the tree at REV (default 8c6a53c, before issue 29's work), checked out into a
  temporary worktree with its own native core built there; `--reference none` leaves it out.

Missions, each with seed 1 and its run log:
- out-and-back (201.6 s simulated), as a user runs it: one `rovernav sim` command a run. Its
  speed-up is the one the command prints and writes to report.json: simulated time over the wall
  time from building the simulation to closing its log (the process's start-up, about 0.6 s of
  imports, is not in it; the table gives the whole command's wall time too);
- a sample of generated arenas (`rovernav arenas --count 200 --seed 1`, every tenth: 20 arenas),
  as trials run them: one after another in one process (a warm-up mission first), so that the
  process's one-time costs (numba's kernels, about 0.3 s; the camera process's start) are paid
  once, not per arena; a speed-up is simulated time over the wall time from building the
  simulation to closing its log.
Figures are medians over `--runs` runs of each mission; the sample's figure is the median over its
arenas of those medians. Every run's outcome and mission time must be the same in every
configuration (the benchmark says so, or fails).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_REFERENCE = "8c6a53c"


def _python() -> str:
    venv = ROOT / ".venv" / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def _prepare_reference(rev: str, where: Path) -> Path:
    """A worktree of `rev` at `where` (its own native core is built on its first run)."""
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "--detach", "-f", str(where), rev], check=True, capture_output=True
    )
    return where


def _sim(tree: Path, mission: str, out: Path, extra: list[str]) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree / "host"))
    started = time.monotonic()
    proc = subprocess.run(
        [
            _python(),
            "-m",
            "rovernav.cli",
            "sim",
            mission,
            "--no-video",
            "--quiet",
            "--seed",
            "1",
            "--out",
            str(out),
            *extra,
        ],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
    )
    command_s = time.monotonic() - started
    report_path = out / "report.json"
    if proc.returncode not in (0, 1) or not report_path.exists():
        raise SystemExit(
            f"bench_sim_speed: {mission} in {tree} failed (exit {proc.returncode}): {proc.stderr.strip()[-400:]}"
        )
    r = json.loads(report_path.read_text())
    return {
        "speedup": r["mission_time_s"] / r["wall_time_s"],
        "wall_s": r["wall_time_s"],
        "command_s": command_s,
        "mission_s": r["mission_time_s"],
        "outcome": r["outcome"],
    }


def _worker(camera: str, missions: list[str]) -> None:
    """Run `missions` one after another in this process, as a trials worker does (numba's kernels
    and the camera process started once), each with its run log; print one JSON line each."""
    import inspect

    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    kw = {"camera_process": camera == "on"} if "camera_process" in inspect.signature(SimOptions).parameters else {}
    out = Path(tempfile.mkdtemp(prefix="rovernav-simspeed-worker-"))
    for i, mission in enumerate(["seed-fig4-8-unknown-obstacle", *missions]):  # the first: a warm-up
        started = time.monotonic()
        sim = Simulation(load_scenario(mission), SimOptions(seed=1, log=out / "run.mcap", **kw))
        sim.run()
        sim.close_log()
        wall_s = time.monotonic() - started
        if i:
            print(
                json.dumps(
                    {"mission": mission, "mission_s": round(sim.t, 3), "wall_s": wall_s, "outcome": sim.outcome}
                ),
                flush=True,
            )
    shutil.rmtree(out, ignore_errors=True)


def _in_process(tree: Path, camera: str, missions: list[str]) -> dict[str, dict]:
    proc = subprocess.run(
        [_python(), str(Path(__file__).resolve()), "--_worker", camera, *missions],
        cwd=tree,
        env=dict(os.environ, PYTHONPATH=str(tree / "host")),
        capture_output=True,
        text=True,
    )
    if proc.returncode != 0:
        raise SystemExit(f"bench_sim_speed: the arenas in {tree} failed: {proc.stderr.strip()[-600:]}")
    got = {}
    for line in proc.stdout.splitlines():
        r = json.loads(line)
        r["speedup"] = r["mission_s"] / r["wall_s"]
        got[r["mission"]] = r
    return got


def main(argv: list[str] | None = None) -> int:
    if argv is None and len(sys.argv) > 2 and sys.argv[1] == "--_worker":
        _worker(sys.argv[2], sys.argv[3:])
        return 0
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="runs of each mission in each configuration (default 3)")
    ap.add_argument("--arenas", type=int, default=20, help="generated arenas in the sample, 0 for none (default 20)")
    ap.add_argument(
        "--reference",
        default=DEFAULT_REFERENCE,
        help=f"git revision to compare with (default {DEFAULT_REFERENCE}), or none",
    )
    ap.add_argument("--json", type=Path, help="write every run's figures here")
    args = ap.parse_args(argv)
    if args.runs < 1 or not 0 <= args.arenas <= 200:
        ap.error("--runs must be at least 1 and --arenas 0 to 200")

    tmp = Path(tempfile.mkdtemp(prefix="rovernav-simspeed-"))
    configs: dict[str, tuple[Path, list[str]]] = {
        "ours": (ROOT, []),
        "ours, one core": (ROOT, ["--camera-process", "off"]),
    }
    ref_tree = None
    try:
        if args.reference != "none":
            ref_tree = _prepare_reference(args.reference, tmp / "reference")
            configs["reference"] = (ref_tree, [])
        missions = ["out-and-back"]
        if args.arenas:
            arena_dir = tmp / "arenas"
            subprocess.run(
                [_python(), "-m", "rovernav.cli", "arenas", "--count", "200", "--seed", "1", "--out", str(arena_dir)],
                cwd=ROOT,
                env=dict(os.environ, PYTHONPATH=str(ROOT / "host")),
                check=True,
                capture_output=True,
            )
            files = sorted(arena_dir.glob("*.toml"))
            missions += [str(p) for p in files[:: max(1, len(files) // args.arenas)][: args.arenas]]
        print(
            f"cores: {len(os.sched_getaffinity(0))} usable; {len(missions)} missions x {args.runs} runs x "
            f"{len(configs)} configurations: {', '.join(configs)}",
            file=sys.stderr,
        )
        for tree, extra in configs.values():  # warm-up: native core builds, numba's cache
            _sim(tree, "seed-fig4-8-unknown-obstacle", tmp / "warm", extra)
        runs: dict[str, dict[str, list[dict]]] = {c: {} for c in configs}
        t0 = time.monotonic()
        for k in range(args.runs):  # out-and-back: the whole command, as a user runs it
            for name, (tree, extra) in configs.items():
                runs[name].setdefault("out-and-back", []).append(_sim(tree, "out-and-back", tmp / "out", extra))
            print(
                f"[out-and-back {k + 1}/{args.runs} {time.monotonic() - t0:4.0f} s] "
                + ", ".join(f"{n} {runs[n]['out-and-back'][-1]['speedup']:.1f}x" for n in configs),
                file=sys.stderr,
                flush=True,
            )
        for k in range(args.runs if len(missions) > 1 else 0):  # the sample: one process, as trials run
            for name, (tree, extra) in configs.items():
                camera = "off" if "off" in extra else "on"
                for mission, r in _in_process(tree, camera, missions[1:]).items():
                    runs[name].setdefault(mission, []).append({**r, "command_s": math.nan})
            print(
                f"[arenas {k + 1}/{args.runs} {time.monotonic() - t0:4.0f} s] "
                + ", ".join(
                    f"{n} {statistics.median(runs[n][m][-1]['speedup'] for m in missions[1:]):.1f}x" for n in configs
                ),
                file=sys.stderr,
                flush=True,
            )
        # Every configuration ran the same missions.
        for mission in missions:
            seen = {(r["outcome"], round(r["mission_s"], 2)) for c in configs for r in runs[c][mission]}
            if len(seen) != 1:
                print(
                    f"bench_sim_speed: {mission} differs between runs or configurations: {sorted(seen)}",
                    file=sys.stderr,
                )
                return 1
    finally:
        if ref_tree is not None:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(ref_tree)], capture_output=True
            )
        shutil.rmtree(tmp, ignore_errors=True)

    med = statistics.median

    def figures(name: str, which: list[str]) -> tuple[float, float, float]:
        per = [runs[name][m] for m in which]
        return (
            med(med(r["speedup"] for r in rs) for rs in per),
            med(med(r["wall_s"] for r in rs) for rs in per),
            med(med(r["command_s"] for r in rs) for rs in per),  # nan for the sample
        )

    rows = [("out-and-back (201.6 s simulated)", ["out-and-back"])]
    if args.arenas:
        rows.append((f"{len(missions) - 1} generated arenas in one process (median)", missions[1:]))
    print(
        f"\nmedian of {args.runs} runs; speed-up = simulated time / wall time (report.json); "
        f"command = the whole `rovernav sim` process\n"
    )
    head = "| missions | configuration | speed-up | wall (s) | command (s) |" + (
        " against the reference |" if ref_tree else ""
    )
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    out_json: dict = {"runs": args.runs, "reference": args.reference, "rows": []}
    for label, which in rows:
        ref = figures("reference", which)[0] if ref_tree else None
        for name in configs:
            s, w, c = figures(name, which)
            ratio = f" {s / ref:.2f}x |" if ref else ""
            cmd = "-" if math.isnan(c) else f"{c:.2f}"
            print(f"| {label} | {name} | **{s:.1f}x** | {w:.2f} | {cmd} |{ratio}")
            out_json["rows"].append(
                {"missions": label, "configuration": name, "speedup": s, "wall_s": w, "command_s": c}
            )
    if args.json:
        out_json["runs_raw"] = runs
        args.json.write_text(json.dumps(out_json, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
