"""Renderer benchmark: milliseconds per 640x480 camera frame as the simulator draws them.

    python benchmarks/bench_render.py [--frames 600] [--runs 5] [--seed 1] [--markers colour|aruco]
    python benchmarks/bench_render.py --against /tmp/render_old.py     # before/after

The scene is the out-and-back arena (four obstacles, the target) with a rover wandering across it
at 0.1 m/s filmed at 30 fps, noise 3 grey levels and a random uneven light, as `rovernav sim`
renders it. Per run (each run a new seed: new light, new path), a renderer draws the arena once
(timed apart, as "first frame") and then `--frames` frames; the figures are the medians over a
run's frames (wall clock and this process's CPU time), then the median of those over the runs.

Besides the whole frame, the parts of this renderer: the arena without the rover (a copy of a noisy
arena and fresh noise round the target) and the rover (drawn and lit in a window round its body).

--against FILE times another version of rovernav/sim/camera.py too (say the one before a change:
`git show REV:host/rovernav/sim/camera.py > /tmp/render_old.py`), interleaved frame by frame with this
one so that a machine's changing load falls on both alike.

Here (2 cores shared with other jobs, load 4-5), against the renderer of fd38c9a (the rover drawn
with 8x8 single-step supersampling, the whole frame's noise every frame): 0.36 ms a frame against
0.80 ms (the rover 0.19 ms of it, the arena with its noise 0.04 ms); the first frame of a scene,
which draws the floor, about 0.2 s CPU for both.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from rovernav.scenario import load_scenario
from rovernav.sim import camera as this_render

ROOT = Path(__file__).resolve().parents[1]


def _load(path: Path):
    spec = importlib.util.spec_from_file_location("rovernav._render_against", path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[spec.name] = module  # type: ignore[union-attr]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _scene(module, markers: str):
    sc = load_scenario(ROOT / "scenarios" / "out-and-back.toml")
    return module.Scene(
        arena_w_m=sc.arena.width_m,
        arena_h_m=sc.arena.height_m,
        obstacles=tuple((o.x_m, o.y_m, o.w_m, o.h_m) for o in sc.obstacles),
        target=(sc.target.x_m, sc.target.y_m),
        marker_kind=markers,
    )


def _poses(rng: np.random.Generator, n: int, w: float, h: float) -> list[tuple[float, float, float]]:
    """A rover wandering at 0.1 m/s, turning now and then, filmed at 30 fps."""
    x, y, hd = 0.4, 0.4, 30.0
    out = []
    for _ in range(n):
        hd += float(rng.normal(0, 2.0))
        x = min(max(x + 0.0033 * math.sin(math.radians(hd)), 0.3), w - 0.3)
        y = min(max(y + 0.0033 * math.cos(math.radians(hd)), 0.3), h - 0.3)
        out.append((x, y, hd))
    return out


def _timed(f) -> tuple[float, float]:
    w0, c0 = time.perf_counter(), time.process_time()
    f()
    return time.perf_counter() - w0, time.process_time() - c0


def run(modules: dict, frames: int, seed: int, markers: str) -> dict:
    setup = np.random.default_rng(seed)
    lighting = this_render.Lighting.random(setup)
    renderers, scenes, rngs = {}, {}, {}
    for name, m in modules.items():
        cam = m.Camera(lighting=m.Lighting(**dataclasses.asdict(lighting)), noise_sigma=3.0)
        renderers[name] = m.Renderer(m.RoverLook(), cam, seed=seed)
        scenes[name] = _scene(m, markers)
        rngs[name] = np.random.default_rng(seed + 1000)
    base = scenes["this"]
    poses = _poses(setup, frames, base.arena_w_m, base.arena_h_m)
    out: dict = {}
    for name, r in renderers.items():
        out[f"{name} first frame"] = [_timed(lambda: r.render(scenes[name], rngs[name]))]
    for name in renderers:
        out[name] = []
    for pose in poses:
        for name, r in renderers.items():
            s = dataclasses.replace(scenes[name], rover=pose)
            out[name].append(_timed(lambda: r.render(s, rngs[name])))
    # This renderer's parts.
    r, rng = renderers["this"], rngs["this"]
    mapping = r.camera.mapping(base.arena_w_m, base.arena_h_m)
    out["  arena, noise"] = [_timed(lambda: r.render(base, rng)) for _ in poses]
    out["  rover"] = [_timed(lambda: r._rover_patch(dataclasses.replace(base, rover=p), mapping)) for p in poses]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--markers", choices=("colour", "aruco"), default="colour")
    ap.add_argument("--against", type=Path, help="another version of rovernav/sim/camera.py to time alongside")
    args = ap.parse_args()
    modules = {"this": this_render}
    if args.against is not None:
        modules["against"] = _load(args.against)
    per_run: dict[str, list[tuple[float, float, float]]] = {}
    for k in range(args.runs):
        got = run(modules, args.frames, args.seed + k, args.markers)
        for name, times in got.items():
            wall = [1000 * t[0] for t in times]
            cpu = [1000 * t[1] for t in times]
            p95 = float(np.percentile(wall, 95)) if len(wall) > 1 else wall[0]
            per_run.setdefault(name, []).append((statistics.median(wall), p95, statistics.median(cpu)))
    print(
        f"rendered 640x480 frames, {args.markers} markers, {args.runs} runs of {args.frames} frames "
        f"(medians over runs of each run's median)"
    )
    print(f"{'':24s} {'wall ms':>8s} {'p95 ms':>8s} {'CPU ms':>8s}")
    order = ["this first frame", "this", "  arena, noise", "  rover"]
    if "against" in modules:
        order += ["against first frame", "against"]
    for name in order:
        rows = per_run[name]
        label = {"this": "this, a frame", "against": "against, a frame"}.get(name, name)
        print(
            f"{label:24s} {statistics.median(r[0] for r in rows):8.3f} {statistics.median(r[1] for r in rows):8.3f} "
            f"{statistics.median(r[2] for r in rows):8.3f}"
        )
    if "against" in modules:
        print(f"against: {args.against}")


if __name__ == "__main__":
    main()
