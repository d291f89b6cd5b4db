"""A fleet's shuttle in the simulator (issue 30's acceptance): several rovers under one camera on one
half-duplex radio, each between its start at the base and its site, round trip after round trip.

    python benchmarks/fleet_shuttle.py [--seeds 1,2,3] [--trips 5] [--arenas 20] [--arena-trips 3]
                                       [--radio clean|loss1|burst2|loss2|loss3|loss5] [--uno]
                                       [--plants nominal|spread|calibrated] [--fleet-only] [--arena-routes]
                                       [--jobs 2] [--json FILE]

Two parts, each printed as a table with the command's figures:
  out-and-back   scenarios/fleet-out-and-back.toml, 3 rovers x TRIPS round trips, every seed; beside
                 each, one rover alone on each of the three rovers' routes (a fleet of one, the same
                 radio discipline: TRIPS round trips from that rover's berth to its site) and the
                 lone rover of `rovernav sim` on rover 1's (its own radio, no slots): trips an hour,
                 and the fleet's over one rover's doing the fleet's trips (the three routes' times
                 added: the same work, one rover) and over one rover's on rover 1's route; contacts,
                 runs stuck (a deadlock: no leg done for 150 s and no rover moved 0.2 m in 60 s, or
                 no leg done for 450 s).
  arenas         ARENAS generated arenas (`rovernav arenas --count 200 --seed 1`, sampled evenly,
                 the solvable ones with a base for 3 rovers), each given starts and sites for 3 rovers
                 (evaluation/fleet_arenas.py), ARENA_TRIPS round trips each: trips done of asked,
                 contacts, stuck runs; with --arena-routes, beside each fleet one rover alone on
                 each of its routes, and the ratio as above.

--fleet-only runs the 3-rover fleet alone on each seed (no rover alone on the routes, no lone
`rovernav sim`): a rate over many seeds (`--seeds 1-10`), the fleet's runs whole, stuck and
crashed, for judging a change to the traffic rules.

--radio loss1 runs both on a radio that loses 1 % of its bytes and flips a bit in 0.1 % (burst2: 2 %
lost in bursts, mean 0.5 s, 10 % of the time; loss2, loss3: 2 and 3 % lost, 0.1 % flipped; loss5:
5 % lost; benchmarks/lossy_radio.py); --uno makes rover 1 the Uno image in simavr (its worst step is
printed); --plants spread gives each rover motors and a gyro of its own, off the firmware's figures
and uncalibrated (off_nominal_plants), --plants calibrated the same rovers each with its own motor
parameters. Exit status 1 when an acceptance figure is missed: 0 contacts and 0 stuck anywhere,
throughput >= 2.5x one rover's doing the same trips on every seed, >= 99 % of the arenas' trips.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
from lossy_radio import RADIOS, solvable  # noqa: E402  (the same radios: clean, loss1, burst2, loss2, loss3, loss5)
from lossy_radio import arenas as sample_arenas  # noqa: E402  (the same sample of generated arenas)

FLEET = "fleet-out-and-back"
MAX_TIME_S = 3600.0
THROUGHPUT_GOAL = 2.5
TRIPS_GOAL = 0.99


class Job(NamedTuple):
    """One simulated run: a fleet of `rovers` on `scenario`; with `route` k (a fleet of one), one
    rover alone on rover k's route, from the scenario's start k to its site k."""

    scenario: str | Path
    rovers: int
    seed: int
    trips: int
    radio: str
    uno: bool = False
    route: int | None = None
    trial: bool = False  # the seen-ground trial
    care: bool = False  # the turn-care trial
    plants: str = "nominal"  # "spread": each rover's motors and gyro its own (off_nominal_plants); "calibrated": and its parameters


def off_nominal_plants(seed: int, count: int) -> tuple:
    """`count` rovers unlike each other and the firmware's figures, for the run of `seed`: rover k's
    motors and gyro as `Setup.random` draws them for the calibration benchmark's set-ups (speed per
    PWM 0.8-1.25x, the right motor 0.95-1.2x the left, dead band 0.8-1.3x, gyro bias up to 0.15
    deg/s, gyro scale 0.97-1.03), none calibrated: the host and firmware keep their defaults. The
    sonar stays where the configuration says (its offset is a calibration's, not the fleet's, to
    find)."""
    sys.path.insert(0, str(ROOT / "host"))
    import dataclasses

    from rovernav.sim.plant import PlantConfig
    from rovernav.sim.setup import Setup

    nominal = PlantConfig()
    return tuple(
        dataclasses.replace(Setup.random(100_000 + 100 * seed + k).plant, sonar_offset_m=nominal.sonar_offset_m)
        for k in range(count)
    )


def calibrated_params(plant) -> dict:
    """The motor parameters `rovernav calibrate rover` would give a rover of `plant` with a perfect
    fit (the fit's own `params`): speed per PWM, dead band and the right motor's bias."""
    sys.path.insert(0, str(ROOT / "host"))
    from rovernav.calibrate.rover.fitting import Fit

    fit = Fit(plant.mm_s_per_pwm, plant.deadband_pwm, plant.right_gain, 0.0, 0.0, ())
    return fit.params()


def run_fleet(job: Job) -> dict:
    """The run `job` names (a Job): its figures."""
    scenario, rovers, seed, trips, radio, uno, route, trial, care, plant_kind = job
    sys.path.insert(0, str(ROOT / "host"))
    import dataclasses

    from rovernav.evaluation.fleet_arenas import FleetPlacementError, fleet_scenario
    from rovernav.radio import ChannelConfig
    from rovernav.scenario import load_scenario
    from rovernav.sim.fleet_runner import FleetOptions, FleetSimulation

    sc = load_scenario(scenario)
    plants = own = None
    if plant_kind != "nominal":
        plants = off_nominal_plants(seed, max(rovers, len(sc.starts)))  # (a generated arena has one start)
        plants = plants[route : route + 1] if route is not None else plants
        if plant_kind == "calibrated":
            own = tuple(calibrated_params(p) for p in plants)
    if route is not None:
        try:  # a generated arena has one start and one site: the fleet's, placed, first
            sc = fleet_scenario(sc, max(3, route + 1))
        except FleetPlacementError as exc:
            return {
                "scenario": sc.name,
                "rovers": rovers,
                "route": route,
                "seed": seed,
                "placed": False,
                "why": str(exc),
            }
        starts, sites = list(sc.starts), list(sc.sites)
        start, site = starts.pop(route), sites.pop(route % len(sites))
        sc = dataclasses.replace(sc, start=start, target=site, more_starts=tuple(starts), more_sites=tuple(sites))
    try:
        sc = fleet_scenario(sc, rovers)
    except FleetPlacementError as exc:
        return {"scenario": sc.name, "rovers": rovers, "seed": seed, "placed": False, "why": str(exc)}
    sim = FleetSimulation(
        sc,
        FleetOptions(
            rovers=rovers,
            seed=seed,
            trips=trips,
            max_time_s=MAX_TIME_S,
            channel=ChannelConfig(half_duplex=True, **RADIOS[radio]),
            rover1="uno" if uno else "native",
            seen_ground_trial=trial,
            turn_care_trial=care,
            plants=plants,
            rover_params=own,
        ),
    )
    sim.run()
    r = sim.report()
    worst = (r.get("uno_timing") or {}).get("worst_step") or {}
    return {
        "scenario": sc.name,
        "rovers": rovers,
        "route": route,
        "seed": seed,
        "placed": True,
        "outcome": r["outcome"],
        "trips_done": r["trips_done"],
        "trips_asked": rovers * trips,
        "time_s": r["mission_time_s"],
        "trips_per_hour": r["trips_per_hour"],
        "contacts": r["contacts"],
        "crash": r["crash"],
        "stuck": r["outcome"] == "stuck",
        "min_separation_m": r["min_rover_separation_m"],
        "holds": sum(x["held"]["times"] for x in r["per_rover"]),
        "air_bytes_per_s": r["radio"]["air_bytes_per_s"],
        "per_rover_link": [x["link"] for x in r["per_rover"]],
        "errors": [x["error"] for x in r["per_rover"] if x["error"]],
        "uno_worst_step_us": worst.get("us"),
        "wall_s": r["wall_time_s"],
        # A stuck fleet's own account: where each rover stood and what held it (fleet_runner's message).
        "stuck_why": next((text for _t, k, text in reversed(sim.events) if k == -1 and text.startswith("stuck")), None),
    }


def run_lone(job: tuple) -> dict:
    """The lone rover of `rovernav sim` on rover 1's start and site: trips an hour."""
    seed, trips, radio = job
    sys.path.insert(0, str(ROOT / "host"))
    from rovernav.config import config_from_dict
    from rovernav.radio import ChannelConfig
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    sc = load_scenario(FLEET)
    cfg = config_from_dict(
        {"arena": {"width_m": sc.arena.width_m, "height_m": sc.arena.height_m}, "mission": {"trips": trips}}
    )
    sim = Simulation(
        sc,
        SimOptions(
            seed=seed, max_time_s=MAX_TIME_S, config=cfg, channel=ChannelConfig(half_duplex=True, **RADIOS[radio])
        ),
    )
    sim.run()
    done = sum(1 for leg in sim.mission.legs if leg.reached) // 2
    return {
        "seed": seed,
        "outcome": sim.outcome,
        "trips_done": done,
        "time_s": sim.t,
        "trips_per_hour": done * 3600 / sim.t,
    }


def placement_problem(scenario: str) -> str | None:
    """Why a generated arena has no base and sites for 3 rovers (None: it has)."""
    sys.path.insert(0, str(ROOT / "host"))
    from rovernav.evaluation.fleet_arenas import FleetPlacementError, fleet_scenario
    from rovernav.scenario import load_scenario

    try:
        fleet_scenario(load_scenario(scenario), 3)
    except FleetPlacementError as exc:
        return str(exc)
    return None


def parse_seeds(text: str) -> list[int]:
    """Seeds from "1,2,3", "1-10" or both ("1-5,8"); ValueError (one line) for anything else."""
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        if not (lo.isdigit() and (not sep or hi.isdigit())):
            raise ValueError(f"--seeds: {part!r} is neither a seed nor a range like 1-10")
        first, last = int(lo), int(hi) if sep else int(lo)
        if last < first:
            raise ValueError(f"--seeds: the range {part!r} runs backwards")
        seeds += range(first, last + 1)
    if not seeds:
        raise ValueError("--seeds: no seed given")
    return seeds


def fleet_rates(rows: list[dict], a) -> bool:
    """The fleet's runs over the seeds (--fleet-only): one line a seed, then the rates. True when
    every run is whole (its trips done, no contact, not stuck)."""
    rows = sorted(rows, key=lambda r: r["seed"])  # (out-and-back's runs are all placed: its own starts)
    plants = "" if a.plants == "nominal" else f", each rover's motors and gyro its own (--plants {a.plants})"
    print(f"\nout-and-back ({FLEET}), the 3-rover fleet alone, {a.trips} round trips a rover, radio {a.radio}{plants}:")
    print("| seed | outcome | trips | time [s] | contacts | holds | what ended it |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        crash = r["crash"] or {}
        why = f"rover {crash.get('rover')} against {crash.get('against')} at {crash.get('t_s')} s" if crash else ""
        why = why or r.get("stuck_why") or "; ".join(e for e in r["errors"] if e)
        print(
            f"| {r['seed']} | {r['outcome']} | {r['trips_done']}/{r['trips_asked']} | {r['time_s']:.0f} | "
            f"{r['contacts']} | {r['holds']} | {why} |"
        )
    whole = [r for r in rows if r["trips_done"] == r["trips_asked"] and not r["contacts"] and not r["stuck"]]
    crashed = sum(1 for r in rows if r["contacts"])
    stuck = sum(1 for r in rows if r["stuck"] and not r["contacts"])
    times = [r["time_s"] for r in whole]
    median = f", median time of the whole runs {statistics.median(times):.0f} s" if times else ""
    print(
        f"fleet runs whole {len(whole)}/{len(rows)}, stuck {stuck}, crashed {crashed}, other {len(rows) - len(whole) - stuck - crashed}"
        f"{median}; trips done {sum(r['trips_done'] for r in rows)}/{sum(r['trips_asked'] for r in rows)}"
    )
    return len(whole) == len(rows)


def arena_ratios(fleets: list[dict], alone: list[dict]) -> list[dict]:
    """The generated arenas' fleets against one rover alone on each of their routes (--arena-routes):
    a table, a row an arena, and its rows. The ratio is the fleet's trips an hour over one rover's
    doing the same trips (the routes' times added); the bound, that ratio with no interference at all
    (the routes' times added over the longest: the fleet cannot finish before its slowest route)."""
    print(
        "\nthe fleet over one rover doing the same trips (each route alone, the same radio discipline):\n"
        "| arena | 3 rovers | each route alone [s] | bound with no interference | **ratio** | holds |\n"
        "|---|---|---|---|---|---|"
    )
    table = []
    for f in sorted(fleets, key=lambda r: r["scenario"]):
        solo = sorted((r for r in alone if r["scenario"] == f["scenario"] and r["placed"]), key=lambda r: r["route"])
        whole = f["outcome"] == "reached" and len(solo) == 3 and all(r["outcome"] == "reached" for r in solo)
        times = [r["time_s"] for r in solo]
        bound = sum(times) / max(times) if whole else 0.0
        ratio = sum(times) / f["time_s"] if whole else 0.0
        table.append(
            {"scenario": f["scenario"], "ratio": ratio, "bound": bound, "alone_s": times, "fleet_s": f["time_s"]}
        )
        print(
            f"| {f['scenario']} | {f['outcome']} {f['trips_done']}/{f['trips_asked']} in {f['time_s']:.0f} s | "
            f"{' / '.join(f'{t:.0f}' for t in times)} | {bound:.2f}x | **{ratio:.2f}x** | {f['holds']} |"
        )
    ratios = [t["ratio"] for t in table if t["ratio"]]
    if ratios:
        print(
            f"ratio over {len(ratios)} arenas whole: median {statistics.median(ratios):.2f}x "
            f"(range {min(ratios):.2f}-{max(ratios):.2f}x), {sum(r >= THROUGHPUT_GOAL for r in ratios)} at "
            f"{THROUGHPUT_GOAL}x or more; bound median {statistics.median(t['bound'] for t in table if t['ratio']):.2f}x"
        )
    return table


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1,2,3", help="seeds: a list and ranges, 1,2,3 or 1-10 (default 1,2,3)")
    ap.add_argument("--trips", type=int, default=5, help="round trips a rover on out-and-back (default 5)")
    ap.add_argument("--arenas", type=int, default=20, help="generated arenas (default 20; 0: none)")
    ap.add_argument("--arena-trips", type=int, default=3, help="round trips a rover on an arena (default 3)")
    ap.add_argument(
        "--arena-routes",
        action="store_true",
        help="arenas: beside each fleet, one rover alone on each of its three routes: the fleet's trips an hour over "
        "one rover's doing the same trips, and the bound with no interference (the routes' times added over the "
        "longest)",
    )
    ap.add_argument("--radio", choices=sorted(RADIOS), default="clean")
    ap.add_argument("--uno", action="store_true", help="rover 1 is the Uno image")
    ap.add_argument("--skip-out-and-back", action="store_true")
    ap.add_argument(
        "--fleet-only",
        action="store_true",
        help="out-and-back: the 3-rover fleet alone on each seed (no rover alone, no ratio): its runs whole, "
        "stuck and crashed over the seeds",
    )
    ap.add_argument(
        "--seen-ground-trial",
        action="store_true",
        help="the host's seen-ground trial: paths over ground already seen driven without the sweeps every 0.3 m, "
        "and a rover Blocked 9 s on its path sent its leg again (off by default; docs/results.md)",
    )
    ap.add_argument(
        "--turn-care-trial",
        action="store_true",
        help="the host's turn-care trial: a rover that refuses a turn held at once and planned afresh from where it "
        "stops, a rover that gave way waiting for the other to pass, no spot aside on a berth (off by default; "
        "docs/results.md)",
    )
    ap.add_argument(
        "--plants",
        choices=("nominal", "spread", "calibrated"),
        default="nominal",
        help="spread: each rover's motors and gyro off the firmware's figures, its own, uncalibrated (speed per PWM "
        "0.8-1.25x, right motor 0.95-1.2x, dead band 0.8-1.3x, gyro bias up to 0.15 deg/s, scale 0.97-1.03); "
        "calibrated: the same rovers, each given its own motor parameters as a perfect `rovernav calibrate rover` "
        "would; nominal (default): every rover the simulator's usual plant",
    )
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    sys.path.insert(0, str(ROOT / "host"))
    from rovernav.evaluation.pool import map_runs

    try:
        seeds = parse_seeds(a.seeds)
    except ValueError as exc:
        print(f"fleet_shuttle: {exc}", file=sys.stderr)
        return 2
    started = time.monotonic()
    out: dict = {"radio": a.radio, "uno": a.uno, "plants": a.plants}
    ok = True
    if not a.skip_out_and_back:
        how = {"trial": a.seen_ground_trial, "care": a.turn_care_trial, "plants": a.plants}
        jobs = [Job(FLEET, 3, s, a.trips, a.radio, uno=a.uno, **how) for s in seeds]
        if not a.fleet_only:
            jobs += [Job(FLEET, 1, s, a.trips, a.radio, route=k, **how) for s in seeds for k in range(3)]
        rows = []
        for _job, row in map_runs(run_fleet, jobs, a.jobs, ordered=False):
            rows.append(row)
            who = "3 rovers" if row["route"] is None else f"1 rover on route {row['route'] + 1}"
            print(
                f"  {row['scenario']} {who} seed {row['seed']}: {row['outcome']}, "
                f"{row['trips_done']}/{row['trips_asked']} trips in {row['time_s']:.0f} s",
                file=sys.stderr,
                flush=True,
            )
        if a.fleet_only:
            ok &= fleet_rates(rows, a)
            out["fleet_runs"] = rows
            seeds = []  # the comparison with one rover below is left out
        lone = {r["seed"]: r for _, r in map_runs(run_lone, [(s, a.trips, a.radio) for s in seeds], a.jobs)}
        if seeds:
            print(f"\nout-and-back ({FLEET}), {a.trips} round trips a rover, radio {a.radio}:")
            print(
                "| seed | 3 rovers | trips/h | 1 rover on each route alone (1, 2, 3) | the same trips by 1 rover: "
                "trips/h | **ratio** | ratio to route 1 alone | lone `rovernav sim` trips/h (the usual plant) | "
                "contacts | stuck | holds "
                "| air B/s |"
            )
            print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        table = []
        for s in seeds:
            three = next(r for r in rows if r["seed"] == s and r["route"] is None)
            solo = [next(r for r in rows if r["seed"] == s and r["route"] == k) for k in range(3)]
            solo_s = sum(r["time_s"] for r in solo)
            solo_done = sum(r["trips_done"] for r in solo)
            one_tph = solo_done * 3600 / solo_s if solo_s else 0.0  # one rover, the fleet's trips one after another
            ratio = three["trips_per_hour"] / one_tph if one_tph else 0.0
            route1 = three["trips_per_hour"] / solo[0]["trips_per_hour"] if solo[0]["trips_per_hour"] else 0.0
            table.append(
                {"seed": s, "three": three, "solo": solo, "lone": lone[s], "ratio": ratio, "ratio_route1": route1}
            )
            solo_text = ", ".join(
                f"{r['trips_done']}/{r['trips_asked']} in {r['time_s']:.0f} s"
                + ("" if r["outcome"] == "reached" else f" ({r['outcome']})")
                for r in solo
            )
            print(
                f"| {s} | {three['outcome']} {three['trips_done']}/{three['trips_asked']} in {three['time_s']:.0f} s | "
                f"{three['trips_per_hour']:.1f} | {solo_text} | {one_tph:.1f} | **{ratio:.2f}x** | {route1:.2f}x | "
                f"{lone[s]['trips_per_hour']:.1f} ({lone[s]['outcome']}) | "
                f"{three['contacts']} | {int(three['stuck'])} | {three['holds']} | {three['air_bytes_per_s']:.0f} |"
            )
            ok &= three["contacts"] == 0 and not three["stuck"] and ratio >= THROUGHPUT_GOAL
            ok &= three["trips_done"] == three["trips_asked"] and all(r["outcome"] == "reached" for r in solo)
        worst = [r["uno_worst_step_us"] for r in rows if r.get("uno_worst_step_us")]
        if worst:
            print(f"rover 1 as the Uno image: worst step {max(worst):.0f} us (goal 5,000)")
            ok &= max(worst) <= 5000
        ratios = [t["ratio"] for t in table]
        if ratios:
            print(
                f"throughput, 3 rovers over 1 rover doing the same trips: median {statistics.median(ratios):.2f}x "
                f"(goal {THROUGHPUT_GOAL}x); over 1 rover on route 1: median "
                f"{statistics.median(t['ratio_route1'] for t in table):.2f}x"
            )
            out["out_and_back"] = table
    if a.arenas:
        # The first ARENAS of the sample that are solvable and have a base for 3 rovers (the others
        # are named, not run: no fleet shuttle fits them).
        paths, no_room = [], []
        for p in [p for p in sample_arenas(a.arenas * 3) if solvable(p)]:
            if len(paths) == a.arenas:
                break
            why = placement_problem(p)
            (no_room if why else paths).append(why or p)
        for why in no_room:
            print(f"  not run: {why}", file=sys.stderr)
        how = {"trial": a.seen_ground_trial, "care": a.turn_care_trial, "plants": a.plants}
        jobs = [Job(p, 3, 1, a.arena_trips, a.radio, uno=a.uno, **how) for p in paths]
        if a.arena_routes:
            jobs += [Job(p, 1, 1, a.arena_trips, a.radio, route=k, **how) for p in paths for k in range(3)]
        rows, alone = [], []
        for _job, row in map_runs(run_fleet, jobs, a.jobs, ordered=False):
            if row.get("route") is not None:
                alone.append(row)
                continue
            rows.append(row)
            print(
                f"  {row['scenario']}: {row.get('outcome', row.get('why'))}, "
                f"{row.get('trips_done')}/{row.get('trips_asked')} trips",
                file=sys.stderr,
                flush=True,
            )
        placed = [r for r in rows if r["placed"]]
        done = sum(r["trips_done"] for r in placed)
        asked = sum(r["trips_asked"] for r in placed)
        contacts = sum(r["contacts"] for r in placed)
        stuck = sum(1 for r in placed if r["stuck"])
        print(
            f"\n{len(placed)} generated arenas with a shuttle for 3 rovers ({len(no_room)} passed over: no base "
            f"for 3), {a.arena_trips} round trips each, radio {a.radio}:"
        )
        print(
            f"trips done {done}/{asked} ({100 * done / max(asked, 1):.1f} %), contacts {contacts}, stuck {stuck}, "
            f"median time {statistics.median([r['time_s'] for r in placed]):.0f} s"
        )
        for r in sorted(placed, key=lambda r: r["scenario"]):
            if r["trips_done"] < r["trips_asked"] or r["contacts"]:
                print(
                    f"  {r['scenario']}: {r['outcome']} {r['trips_done']}/{r['trips_asked']}; "
                    f"{r['crash'] or ''} {'; '.join(e for e in r['errors'] if e)}"
                )
        ok &= contacts == 0 and stuck == 0 and done >= TRIPS_GOAL * asked
        out["arenas"] = rows
        if a.arena_routes:
            out["arena_routes"] = arena_ratios(placed, alone)
    print(f"({time.monotonic() - started:.0f} s wall)")
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
