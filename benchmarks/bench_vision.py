"""Vision benchmark: milliseconds per 640x480 frame and accuracy, on rendered frames with sensor
noise and uneven light, for the colour markers and for ArUco tags.

    python benchmarks/bench_vision.py [--frames 300] [--runs 3] [--seed 1]

Two ways of locating are timed: "tracking" (consecutive frames of a moving rover, the way the
host runs: both locators look for each marker in a window around where it was in the last frame
first, and in the whole frame only when that window does not settle it) and "cold" (every frame
alone, random poses, no memory: the whole frame is searched). Times are the median and 95th
percentile over a run's frames, then the median of those over the runs (each run a new seed: new
light, new poses). Accuracy is over all runs' frames together.

For the colour markers the previous implementation (rovernav.vision.colour_markers_reference:
the marker finder and the pixel-to-arena mapping as they were before they were made faster)
locates every frame too, its order with the current one alternating from frame to frame. "ref ms"
is its median time, "speed-up" the median over the runs of its median divided by the current
one's, both measured on the same frames in the same run; the two must give the same detections,
bit for bit ("differ" counts the frames where they do not).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path

import numpy as np

from rovernav.angles import wrap_deg  # noqa: E402
from rovernav.sim.camera import Camera, Lighting, Renderer, RoverLook, Scene
from rovernav.vision import Locator, VisionConfig
from rovernav.vision.colour_markers_reference import reference_locator

W, H = 2.36, 1.75


def run(kind: str, frames: int, seed: int, tracking: bool) -> dict:
    cfg = VisionConfig(markers=kind)
    rng = np.random.default_rng(seed)
    renderer = Renderer(RoverLook.for_vision(cfg), Camera(lighting=Lighting.random(rng), noise_sigma=3.0), seed=seed)
    loc = Locator(cfg, W, H)
    ref = reference_locator(cfg, W, H) if kind == "colour" else None
    x, y, h = 0.4, 0.4, 30.0
    t_loc, t_ref, t_ren, pos_mm, head_deg, misses, differ = [], [], [], [], [], 0, 0
    for i in range(frames):
        if tracking:  # a rover wandering at 0.1 m/s, turning now and then, filmed at 30 fps
            h += float(rng.normal(0, 2.0))
            x = min(max(x + 0.0033 * math.sin(math.radians(h)), 0.3), W - 0.3)
            y = min(max(y + 0.0033 * math.cos(math.radians(h)), 0.3), H - 0.3)
        else:
            x, y, h = rng.uniform(0.3, W - 0.3), rng.uniform(0.3, H - 0.3), rng.uniform(-180, 180)
            loc.reset()
            if ref is not None:
                ref.reset()
        scene = Scene(rover=(x, y, h), target=(2.0, 1.4), obstacles=((1.2, 0.9, 0.2, 0.2),), marker_kind=kind)
        t0 = time.perf_counter()
        frame = renderer.render(scene, rng)
        t_ren.append(time.perf_counter() - t0)
        order = [loc] if ref is None else [loc, ref] if i % 2 == 0 else [ref, loc]  # alternating
        for locator in order:
            t1 = time.perf_counter()
            d = locator.locate(frame, i / 30.0)
            (t_loc if locator is loc else t_ref).append(time.perf_counter() - t1)
            if locator is loc:
                det = d
            else:
                ref_det = d
        if ref is not None:
            differ += repr(ref_det) != repr(det)
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
        "ref_ms_median": 1000 * statistics.median(t_ref) if t_ref else None,
        "speed_up": statistics.median(t_ref) / statistics.median(t_loc) if t_ref else None,
        "differ": differ,
        "render_ms_median": 1000 * statistics.median(t_ren),
        "pos_mm": pos_mm,
        "head_deg": head_deg,
    }


def combine(runs: list[dict]) -> dict:
    """Medians over runs for times; accuracy over every frame of every run."""
    out = dict(runs[0])
    for key in ("locate_ms_median", "locate_ms_p95", "render_ms_median", "ref_ms_median", "speed_up"):
        out[key] = statistics.median(r[key] for r in runs) if runs[0][key] is not None else None
    pos = [v for r in runs for v in r["pos_mm"]]
    head = [v for r in runs for v in r["head_deg"]]
    out.update(
        pos_mm_median=statistics.median(pos),
        pos_mm_max=max(pos),
        heading_deg_median=statistics.median(head),
        heading_deg_max=max(head),
        misses=sum(r["misses"] for r in runs),
        differ=sum(r["differ"] for r in runs),
        frames=sum(r["frames"] for r in runs),
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=300, help="frames per run (default 300)")
    ap.add_argument("--runs", type=int, default=3, help="runs, each with its own seed (default 3)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the first run (default 1)")
    ap.add_argument("--json", type=Path, help="also write each row's figures here (benchmarks/speed_table.py)")
    args = ap.parse_args()
    rows = []
    print(
        f"{os.cpu_count()} cores; {args.runs} runs of {args.frames} frames, 640x480, noise sigma 3, uneven light; "
        f"times: median over runs of each run's median / 95th percentile"
    )
    print(
        f"{'markers':<8} {'mode':<9} {'locate ms':>10} {'p95':>6} {'ref ms':>7} {'speed-up':>9} {'differ':>7} "
        f"{'render ms':>10} {'pos mm':>7} {'max':>6} {'head deg':>9} {'max':>6} {'misses':>7}"
    )
    for kind in ("colour", "aruco"):
        for tracking in (True, False):
            r = combine([run(kind, args.frames, args.seed + i, tracking) for i in range(args.runs)])
            rows.append({k: v for k, v in r.items() if isinstance(v, (int, float, str)) or v is None})
            ref = "-" if r["ref_ms_median"] is None else f"{r['ref_ms_median']:.3f}"
            up = "-" if r["speed_up"] is None else f"{r['speed_up']:.2f}x"
            differ = "-" if r["ref_ms_median"] is None else str(r["differ"])
            print(
                f"{r['kind']:<8} {r['mode']:<9} {r['locate_ms_median']:10.3f} {r['locate_ms_p95']:6.3f} {ref:>7} "
                f"{up:>9} {differ:>7} {r['render_ms_median']:10.2f} {r['pos_mm_median']:7.2f} {r['pos_mm_max']:6.2f} "
                f"{r['heading_deg_median']:9.2f} {r['heading_deg_max']:6.2f} {r['misses']:7d}"
            )
    if args.json:
        args.json.write_text(json.dumps({"runs": args.runs, "frames": args.frames, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
