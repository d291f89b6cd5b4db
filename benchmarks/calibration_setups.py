"""Set-ups that are not the defaults, calibrated from what the camera sees, then flown.

    python benchmarks/calibration_setups.py [--setups 20] [--first 9001] [--jobs 2] [--json FILE]

Each set-up (rovernav.sim.setup.Setup.random(seed), seeds from --first on, which nothing was
tuned on) has its own marker colours, light, camera tilt and turn, and motors and gyro off the
firmware's figures. For each: three frames of the scenario at its start (the four shared
scenarios in turn) go to `calibrate_camera` with the stickers' colour words; then

- the arena's corners found against the true ones (pixels, worst of four);
- `calibrate rover`'s runs with the calibrated camera: the fitted speed per PWM, dead band,
  right motor's strength and gyro scale against the plant's true figures (per cent), the gyro's
  bias (deg/s) and the sonar's offset from the bench's wall (mm);
- the locator's position error over 12 random rover poses with the calibrated settings, and with
  the true settings (the true corners, ranges round the true hues): the median of each;
- a mission with the calibrated configuration (camera and motors), and one with the default
  configuration.

It prints a row per set-up and the totals; exit status 1 when a calibrated mission does not reach
or collides, or calibration fails, or a motor figure is more than 5 % off, the bias more than
0.01 deg/s or the sonar's offset more than 5 mm.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHARED = ["seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles", "out-and-back"]


def run_one(job: tuple[int, str]) -> dict:
    seed, scenario_name = job
    sys.path.insert(0, str(ROOT / "host"))
    import numpy as np

    from rovernav.calibrate import rover as cr
    from rovernav.calibrate.camera import CalibrationFailed, calibrate_camera
    from rovernav.config import config_from_dict
    from rovernav.link import messages_gen as mg
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation
    from rovernav.sim.setup import Setup, pose_errors, true_vision

    started = time.monotonic()
    sc = load_scenario(scenario_name)
    setup = Setup.random(seed)
    row = {
        "seed": seed,
        "scenario": scenario_name,
        "colours": setup.colour_words(),
        "light": round(setup.lighting.level, 2),
    }
    try:
        result = calibrate_camera(
            setup.calibration_frames(sc, 3, rng_seed=seed),
            sc.arena.width_m,
            sc.arena.height_m,
            words=setup.colour_words(),
        )
    except CalibrationFailed as exc:
        row.update(calibrated=False, error=str(exc), wall_s=round(time.monotonic() - started, 1))
        return row
    row["corner_err_px"] = round(
        float(np.hypot(*(np.array(result.corners_px) - np.array(setup.corners_px)).T).max()), 2
    )
    for key, vision in (
        ("pose_err_mm", result.vision()),
        ("pose_err_true_mm", true_vision(setup, sc.arena.width_m, sc.arena.height_m)),
    ):
        errors = pose_errors(setup, vision, sc, n=12, seed=seed)
        found = [e for e, _ in errors if e is not None]
        row[key] = round(1000 * statistics.median(found), 1) if found else None
        row[key.replace("err", "found")] = len(found)
    arena = {"width_m": sc.arena.width_m, "height_m": sc.arena.height_m}
    camera_only = config_from_dict({"arena": arena, "vision": result.vision().to_dict()})
    try:
        runs = cr.runs_sim(camera_only, setup=setup, seed=seed)
        motors = cr.fit(runs, cr.sim_bench(camera_only)[2])
    except cr.CalibrationFailed as exc:
        row.update(calibrated=False, error=f"calibrate rover: {exc}", wall_s=round(time.monotonic() - started, 1))
        return row
    p = setup.plant
    row["motor_err_pct"] = {
        "mm_s_per_pwm": round(100 * (motors.mm_s_per_pwm / p.mm_s_per_pwm - 1), 2),
        "deadband_pwm": round(100 * (motors.deadband_pwm / p.deadband_pwm - 1), 2),
        "right_gain": round(100 * (motors.right_gain / p.right_gain - 1), 2),
        "gyro_scale": (None if motors.gyro_scale is None else round(100 * (motors.gyro_scale / p.gyro_scale - 1), 2)),
    }
    # The gyro's bias: the plant's own over the still window, against the fit's (deg/s); the
    # sonar's offset against the plant's (mm).
    window = [
        b
        for t, b in runs[0].true_bias
        if runs[0].status and runs[0].status[0][0] + cr.BIAS_SKIP_S <= t <= runs[0].status[0][0] + cr.STILL_S
    ]
    row["gyro_bias_dps"] = {
        "true": round(statistics.fmean(window), 4) if window else None,
        "fit": round(motors.gyro_bias[0], 4) if isinstance(motors.gyro_bias, tuple) else None,
    }
    row["sonar_offset_mm"] = {
        "true": round(1000 * p.sonar_offset_m, 1),
        "fit": round(1000 * motors.sonar[0], 1) if isinstance(motors.sonar, tuple) else None,
    }
    rover = {mg.PARAMS[k].name: v for k, v in motors.params().items()}
    for name, table in (
        (
            "with_calibration",
            {"arena": arena, "vision": result.vision().to_dict(), "rover": rover, "planner": motors.planner()},
        ),
        ("with_defaults", {"arena": arena}),
    ):
        sim = Simulation(sc, SimOptions(seed=1, max_time_s=400, setup=setup, config=config_from_dict(table)))
        sim.run()
        row[name] = {
            "outcome": sim.outcome,
            "time_s": round(sim.t, 1),
            "collisions": sim.collisions,
            "error": sim.mission.error,
        }
    row.update(calibrated=True, wall_s=round(time.monotonic() - started, 1))
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setups", type=int, default=20)
    ap.add_argument("--first", type=int, default=9001, help="the first set-up seed (default 9001)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", help="write every row here")
    a = ap.parse_args()
    jobs = [(a.first + i, SHARED[i % len(SHARED)]) for i in range(a.setups)]
    t0 = time.monotonic()
    rows = []
    sys.path.insert(0, str(ROOT / "host"))
    from rovernav.evaluation.pool import map_runs

    for _, row in map_runs(run_one, jobs, a.jobs):
        rows.append(row)
        if not row["calibrated"]:
            print(f"{row['seed']} {row['scenario']}: calibration failed: {row['error']}", flush=True)
            continue
        c, d = row["with_calibration"], row["with_defaults"]
        print(
            f"{row['seed']} {row['scenario']:<30} {'/'.join(row['colours'].values()):<22} light {row['light']:.2f}  "
            f"corners {row['corner_err_px']:.2f} px  pose {row['pose_err_mm']:.1f} mm (true settings "
            f"{row['pose_err_true_mm']:.1f})  motors {'/'.join(f'{v:+.1f}' for v in row['motor_err_pct'].values())} %"
            f"  bias {row['gyro_bias_dps']['fit']}/{row['gyro_bias_dps']['true']} deg/s"
            f"  sonar {row['sonar_offset_mm']['fit']}/{row['sonar_offset_mm']['true']} mm"
            f"  calibrated: {c['outcome']} {c['time_s']} s, "
            f"{c['collisions']} coll.  default: {d['outcome']} ({d['error'] or ''})",
            flush=True,
        )
    ok = [r for r in rows if r["calibrated"]]
    reached = [
        r for r in ok if r["with_calibration"]["outcome"] == "reached" and r["with_calibration"]["collisions"] == 0
    ]
    default_failed = [r for r in ok if r["with_defaults"]["outcome"] != "reached" or r["with_defaults"]["collisions"]]
    print(
        f"\n{len(rows)} set-ups (seeds {a.first}-{a.first + a.setups - 1}), {time.monotonic() - t0:.0f} s with "
        f"{a.jobs} processes"
    )
    print(
        f"calibrated: {len(ok)}/{len(rows)}; missions reached with 0 collisions: {len(reached)}/{len(rows)}; "
        f"collisions {sum(r['with_calibration']['collisions'] for r in ok)}"
    )
    if ok:
        print(
            f"arena corners: worst {max(r['corner_err_px'] for r in ok):.2f} px; pose error median of medians "
            f"{statistics.median(r['pose_err_mm'] for r in ok):.1f} mm calibrated, "
            f"{statistics.median(r['pose_err_true_mm'] for r in ok):.1f} mm with the true settings"
        )
        worst = {
            k: max(abs(r["motor_err_pct"][k] if r["motor_err_pct"][k] is not None else 99.0) for r in ok)
            for k in ok[0]["motor_err_pct"]
        }
        print("motor figures, worst error: " + ", ".join(f"{k} {v:.1f} %" for k, v in worst.items()))
        bias = [
            abs(r["gyro_bias_dps"]["fit"] - r["gyro_bias_dps"]["true"])
            for r in ok
            if r["gyro_bias_dps"]["fit"] is not None and r["gyro_bias_dps"]["true"] is not None
        ]
        sonar = [
            abs(r["sonar_offset_mm"]["fit"] - r["sonar_offset_mm"]["true"])
            for r in ok
            if r["sonar_offset_mm"]["fit"] is not None
        ]
        print(
            f"gyro bias: measured in {len(bias)}/{len(ok)}, error median {statistics.median(bias) if bias else 0:.4f}, "
            f"worst {max(bias) if bias else 0:.4f} deg/s (true biases up to "
            f"{max(abs(r['gyro_bias_dps']['true'] or 0) for r in ok):.3f}); sonar offset: measured in "
            f"{len(sonar)}/{len(ok)}, error median {statistics.median(sonar) if sonar else 0:.1f}, worst "
            f"{max(sonar) if sonar else 0:.1f} mm"
        )
    print(f"default configuration: failed in {len(default_failed)}/{len(ok)}")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    motors_ok = all(v is not None and abs(v) <= 5.0 for r in ok for v in r["motor_err_pct"].values())
    # The bias within 0.01 deg/s (a tenth of the largest drawn), the offset within 5 mm.
    motors_ok = motors_ok and all(
        r["gyro_bias_dps"]["fit"] is not None
        and abs(r["gyro_bias_dps"]["fit"] - r["gyro_bias_dps"]["true"]) <= 0.01
        and r["sonar_offset_mm"]["fit"] is not None
        and abs(r["sonar_offset_mm"]["fit"] - r["sonar_offset_mm"]["true"]) <= 5.0
        for r in ok
    )
    return 0 if len(reached) == len(rows) and motors_ok else 1


if __name__ == "__main__":
    sys.exit(main())
