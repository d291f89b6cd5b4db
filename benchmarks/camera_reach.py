"""How large an arena one 640 x 480 camera serves: the locator's error against the arena's size.

    python benchmarks/camera_reach.py [--poses 100] [--widths 2.36,3,3.5,4,4.5,5,5.5,6] [--json FILE]

For each width W (the arena W x 0.75 W, the frame's shape, the camera straight down and its frame
spanning the arena, the simulator's renderer with its noise, blur and light, the usual markers:
colour squares of 5 cm): the rover at --poses random poses, each located in one frame by the
locator with the default configuration. Printed per size: pixels per centimetre of floor, the
share of frames the rover was found in, the position error (median, 95th percentile, worst, mm)
and the heading error (RMS, 95th percentile, degrees).

An arena is served when the rover is found in at least 99 % of frames, the position error's
95th percentile is at most 10 mm (a fifth of the 50 mm sonar margin the planner keeps) and the
heading error's RMS is at most 1 degree (the sd the rover's estimator assumes of a FIX's
heading). The last line names the largest width served; exit status 1 if 4 m (the cellular
family's largest) is not.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "host"))

FOUND_MIN = 0.99
POSITION_P95_MAX_MM = 10.0
HEADING_RMS_MAX_DEG = 1.0


def measure(width_m: float, poses: int, seed: int) -> dict:
    from rovernav.scenario import Arena, Mission, Pose, Scenario, Target
    from rovernav.sim.setup import Setup, pose_errors
    from rovernav.vision.config import VisionConfig

    height_m = round(0.75 * width_m, 3)
    scenario = Scenario(
        name="reach",
        arena=Arena(width_m, height_m),
        start=Pose(0.3, 0.3, 0.0),
        target=Target(width_m - 0.3, height_m - 0.3),
        mission=Mission("reach", 1),
        obstacles=(),
    )
    errors = pose_errors(Setup(corner_tags=False), VisionConfig(), scenario, n=poses, seed=seed)
    found = [(p, h) for p, h in errors if p is not None]
    row = {
        "width_m": width_m,
        "height_m": height_m,
        "px_per_cm": round(640 / (100 * width_m), 2),
        "found": len(found),
        "poses": poses,
    }
    if found:
        pos = sorted(1000 * p for p, _ in found)
        head = sorted(abs(h) for _, h in found)
        row.update(
            position_median_mm=round(statistics.median(pos), 2),
            position_p95_mm=round(pos[min(len(pos) - 1, int(0.95 * len(pos)))], 2),
            position_max_mm=round(pos[-1], 2),
            heading_rms_deg=round(math.sqrt(statistics.fmean(h * h for h in head)), 3),
            heading_p95_deg=round(head[min(len(head) - 1, int(0.95 * len(head)))], 3),
        )
    row["served"] = bool(
        found
        and len(found) >= FOUND_MIN * poses
        and row["position_p95_mm"] <= POSITION_P95_MAX_MM
        and row["heading_rms_deg"] <= HEADING_RMS_MAX_DEG
    )
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=100, help="rover poses a size (default 100)")
    ap.add_argument("--widths", default="2.36,3,3.5,4,4.5,5,5.5,6", help="arena widths [m], comma-separated")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args()
    widths = [float(w) for w in a.widths.split(",")]
    t0 = time.monotonic()
    rows = []
    print(f"{'arena':>12}  px/cm  found     position mm (median p95 max)   heading deg (RMS p95)  served")
    for w in widths:
        r = measure(w, a.poses, a.seed)
        rows.append(r)
        arena = f"{r['width_m']:g} x {r['height_m']:g}"
        if r["found"]:
            print(
                f"{arena:>12}  {r['px_per_cm']:5.2f}  {r['found']:>3}/{r['poses']:<3}  "
                f"{r['position_median_mm']:8.2f} {r['position_p95_mm']:6.2f} {r['position_max_mm']:7.2f}"
                f"          {r['heading_rms_deg']:6.3f} {r['heading_p95_deg']:6.3f}        {'yes' if r['served'] else 'no'}",
                flush=True,
            )
        else:
            print(
                f"{arena:>12}  {r['px_per_cm']:5.2f}  {0:>3}/{r['poses']:<3}  (the rover never found)   no", flush=True
            )
    served = [r["width_m"] for r in rows if r["served"]]
    largest = max((w for w in served if all(r["served"] for r in rows if r["width_m"] <= w)), default=None)
    print(f"\n{len(widths)} sizes, {a.poses} poses each, {time.monotonic() - t0:.0f} s")
    print(
        f"served (found >= {100 * FOUND_MIN:.0f} %, position p95 <= {POSITION_P95_MAX_MM:g} mm, heading RMS <= "
        f"{HEADING_RMS_MAX_DEG:g} deg): up to {largest:g} m wide"
        if largest
        else "served: none"
    )
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    return 0 if largest is not None and largest >= 4.0 else 1


if __name__ == "__main__":
    sys.exit(main())
