"""Vision benchmark: milliseconds per 640x480 frame and accuracy, on rendered frames with sensor
noise and uneven light, for the colour markers and for ArUco tags.

    python benchmarks/bench_vision.py [--frames 300] [--runs 3] [--seed 1]

Two ways of locating are timed: "tracking" (consecutive frames of a moving rover, the way the
host runs; the ArUco locator then searches windows around the tags' last places first, the colour
locator always searches the whole frame) and "cold" (every frame alone, random poses, no memory).
Times are the median and 95th percentile over a run's frames, then the median of those over the
runs (each run a new seed: new light, new poses). Accuracy is over all runs' frames together.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np

from rovernav.angles import wrap_deg  # noqa: E402
from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.vision import Locator, VisionConfig

W, H = 2.36, 1.75


def run(kind: str, frames: int, seed: int, tracking: bool) -> dict:
    cfg = VisionConfig(markers=kind)
    rng = np.random.default_rng(seed)
    renderer = Renderer(RoverLook.for_vision(cfg), Camera(lighting=Lighting.random(rng), noise_sigma=3.0), seed=seed)
    loc = Locator(cfg, W, H)
    x, y, h = 0.4, 0.4, 30.0
    t_loc, t_ren, pos_mm, head_deg, misses = [], [], [], [], 0
    for i in range(frames):
        if tracking:  # a rover wandering at 0.1 m/s, turning now and then, filmed at 30 fps
            h += float(rng.normal(0, 2.0))
            x = min(max(x + 0.0033 * math.sin(math.radians(h)), 0.3), W - 0.3)
            y = min(max(y + 0.0033 * math.cos(math.radians(h)), 0.3), H - 0.3)
        else:
            x, y, h = rng.uniform(0.3, W - 0.3), rng.uniform(0.3, H - 0.3), rng.uniform(-180, 180)
            loc.reset()
        scene = Scene(rover=(x, y, h), target=(2.0, 1.4), obstacles=((1.2, 0.9, 0.2, 0.2),), marker_kind=kind)
        t0 = time.perf_counter()
        frame = renderer.render(scene, rng)
        t1 = time.perf_counter()
        det = loc.locate(frame, i / 30.0)
        t2 = time.perf_counter()
        t_ren.append(t1 - t0)
        t_loc.append(t2 - t1)
        if det.rover is None:
            misses += 1
            continue
        pos_mm.append(1000 * math.hypot(det.rover[0] - x, det.rover[1] - y))
        head_deg.append(abs(wrap_deg(det.rover[2] - h)))
    q95 = lambda v: float(np.percentile(v, 95))  # noqa: E731
    return {
        "kind": kind,
        "mode": "tracking" if tracking else "cold",
        "frames": frames,
        "misses": misses,
        "locate_ms_median": 1000 * statistics.median(t_loc),
        "locate_ms_p95": 1000 * q95(t_loc),
        "render_ms_median": 1000 * statistics.median(t_ren),
        "pos_mm": pos_mm,
        "head_deg": head_deg,
    }


def combine(runs: list[dict]) -> dict:
    """Medians over runs for times; accuracy over every frame of every run."""
    out = dict(runs[0])
    for key in ("locate_ms_median", "locate_ms_p95", "render_ms_median"):
        out[key] = statistics.median(r[key] for r in runs)
    pos = [v for r in runs for v in r["pos_mm"]]
    head = [v for r in runs for v in r["head_deg"]]
    out.update(
        pos_mm_median=statistics.median(pos),
        pos_mm_max=max(pos),
        heading_deg_median=statistics.median(head),
        heading_deg_max=max(head),
        misses=sum(r["misses"] for r in runs),
        frames=sum(r["frames"] for r in runs),
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=300, help="frames per run (default 300)")
    ap.add_argument("--runs", type=int, default=3, help="runs, each with its own seed (default 3)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the first run (default 1)")
    args = ap.parse_args()
    print(
        f"{os.cpu_count()} cores; {args.runs} runs of {args.frames} frames, 640x480, noise sigma 3, uneven light; "
        f"times: median over runs of each run's median / 95th percentile"
    )
    print(
        f"{'markers':<8} {'mode':<9} {'locate ms':>10} {'p95':>6} {'render ms':>10} {'pos mm':>7} {'max':>6} "
        f"{'head deg':>9} {'max':>6} {'misses':>7}"
    )
    for kind in ("colour", "aruco"):
        for tracking in (True, False):
            r = combine([run(kind, args.frames, args.seed + i, tracking) for i in range(args.runs)])
            print(
                f"{r['kind']:<8} {r['mode']:<9} {r['locate_ms_median']:10.2f} {r['locate_ms_p95']:6.2f} "
                f"{r['render_ms_median']:10.2f} {r['pos_mm_median']:7.2f} {r['pos_mm_max']:6.2f} "
                f"{r['heading_deg_median']:9.2f} {r['heading_deg_max']:6.2f} {r['misses']:7d}"
            )


if __name__ == "__main__":
    main()
