"""benchmarks/fleet_shuttle.py's seeds and its rates over the fleet's runs (--fleet-only), on
made-up runs."""

from __future__ import annotations

from types import SimpleNamespace

import pytest


def test_seeds_are_lists_and_ranges_and_anything_else_is_one_line(benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    assert bench.parse_seeds("1,2,3") == [1, 2, 3]
    assert bench.parse_seeds("1-5,8") == [1, 2, 3, 4, 5, 8]
    assert bench.parse_seeds(" 7 ") == [7]
    for bad, says in (("3-1", "backwards"), ("x", "neither"), ("1-", "neither"), (",", "no seed")):
        with pytest.raises(ValueError, match=says):
            bench.parse_seeds(bad)
    assert set(bench.RADIOS) >= {"clean", "loss1", "burst2", "loss5"}  # the lossy-radio benchmark's radios


def _row(seed, done, outcome="reached", contacts=0, crash=None):
    return {
        "seed": seed,
        "outcome": outcome,
        "trips_done": done,
        "trips_asked": 15,
        "time_s": 1000.0 + seed,
        "contacts": contacts,
        "holds": 3,
        "crash": crash,
        "stuck": outcome == "stuck",
        "errors": [],
    }


def test_the_fleets_rates_count_whole_stuck_and_crashed_runs(capsys, benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    a = SimpleNamespace(trips=5, radio="clean", plants="nominal")
    crash = {"rover": 2, "against": "rover 3", "t_s": 99.0}
    rows = [_row(2, 15), _row(1, 15), _row(3, 6, "stuck"), _row(4, 2, "crashed", 1, crash)]
    rows[2]["stuck_why"] = "stuck: no rover finished a leg for 150 s; rover 1 idle at (0.50, 0.99) m, held 90 s (x)"
    assert bench.fleet_rates(rows, a) is False
    out = capsys.readouterr().out
    assert "fleet runs whole 2/4, stuck 1, crashed 1, other 0" in out
    assert "median time of the whole runs 1002 s" in out and "trips done 38/60" in out
    assert "rover 2 against rover 3 at 99.0 s" in out
    assert "| stuck: no rover finished a leg for 150 s; rover 1 idle at (0.50, 0.99) m, held 90 s (x) |" in out
    lines = [line for line in out.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert [line.split("|")[1].strip() for line in lines] == ["1", "2", "3", "4"]  # by seed
    assert bench.fleet_rates([_row(1, 15)], a) is True


def test_a_spread_fleet_is_rovers_unlike_each_other_and_the_firmwares_figures(benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    from rovernav.sim.plant import PlantConfig

    nominal = PlantConfig()
    plants = bench.off_nominal_plants(3, 4)
    assert plants == bench.off_nominal_plants(3, 4)  # the same rovers for the same seed
    assert plants != bench.off_nominal_plants(4, 4)
    assert len({p.mm_s_per_pwm for p in plants}) == 4  # each rover its own motors
    for p in plants:
        assert 0.8 * nominal.mm_s_per_pwm <= p.mm_s_per_pwm <= 1.25 * nominal.mm_s_per_pwm
        assert 0.95 <= p.right_gain <= 1.2 and 0.97 <= p.gyro_scale <= 1.03
        assert 0.8 * nominal.deadband_pwm <= p.deadband_pwm <= 1.3 * nominal.deadband_pwm
        assert p.sonar_offset_m == nominal.sonar_offset_m  # where the configuration says


def test_each_rover_of_a_simulated_fleet_drives_its_own_plant():
    import dataclasses

    from rovernav.scenario import load_scenario
    from rovernav.sim.fleet_runner import FleetOptions, FleetSimulation
    from rovernav.sim.plant import PlantConfig

    mine = (dataclasses.replace(PlantConfig(), mm_s_per_pwm=1.9), dataclasses.replace(PlantConfig(), right_gain=1.2))
    sim = FleetSimulation(load_scenario("fleet-out-and-back"), FleetOptions(rovers=3, max_time_s=1.0, plants=mine))
    assert [r.plant.cfg for r in sim.rovers] == [mine[0], mine[1], PlantConfig()]  # the rest: `plant`
    sim.run()
    assert sim.report()["contacts"] == 0


def test_a_calibrated_rover_is_given_its_own_motor_parameters_over_the_configurations(benchmark_module):
    bench = benchmark_module("fleet_shuttle")
    from rovernav.config import config_from_dict
    from rovernav.fleet.host import FLEET_ROVER_PARAMS, fleet_specs
    from rovernav.link import messages_gen as mg
    from rovernav.scenario import load_scenario

    plant = bench.off_nominal_plants(2, 1)[0]
    own = bench.calibrated_params(plant)
    assert own[mg.Param.MOTOR_DEADBAND_PWM] == round(plant.deadband_pwm)
    assert (
        abs(
            mg.PARAMS[mg.Param.SPEED_MM_S_PER_PWM_X1000].to_raw(plant.mm_s_per_pwm)
            - own[mg.Param.SPEED_MM_S_PER_PWM_X1000]
        )
        <= 1
    )
    sc = load_scenario("fleet-out-and-back")
    cfg = config_from_dict({"arena": {"width_m": sc.arena.width_m, "height_m": sc.arena.height_m}})
    plain = fleet_specs(sc, cfg, 3, 100)
    specs = fleet_specs(sc, cfg, 3, 100, own=(own,))
    mine = dict(specs[0].rover_params)
    assert all(mine[p] == v for p, v in own.items())  # rover 1's own, over the configuration's
    assert all(mine[p] == v for p, v in FLEET_ROVER_PARAMS)  # and a fleet rover's still
    assert len(specs[0].rover_params) == len(mine)  # each said once
    assert [s.rover_params for s in specs[1:]] == [s.rover_params for s in plain[1:]]  # the others: none of their own


def test_the_arenas_ratio_is_the_routes_alone_added_over_the_fleets_time(capsys, benchmark_module):
    bench = benchmark_module("fleet_shuttle")

    def run(name, route, time_s, outcome="reached"):
        return {
            "scenario": name,
            "route": route,
            "placed": True,
            "outcome": outcome,
            "time_s": time_s,
            "trips_done": 6,
            "trips_asked": 6 if route is None else 2,
            "holds": 4,
        }

    fleets = [run("b", None, 400.0), run("a", None, 300.0, "stuck")]
    alone = [run("b", 2, 300.0), run("b", 0, 200.0), run("b", 1, 100.0)]
    alone += [run("a", k, 100.0) for k in range(3)]
    table = bench.arena_ratios(fleets, alone)
    b = next(t for t in table if t["scenario"] == "b")
    assert b["ratio"] == pytest.approx(600.0 / 400.0) and b["bound"] == pytest.approx(600.0 / 300.0)
    assert b["alone_s"] == [200.0, 100.0, 300.0]  # routes 1, 2, 3 in order
    assert next(t for t in table if t["scenario"] == "a")["ratio"] == 0.0  # a stuck fleet has no ratio
    out = capsys.readouterr().out
    assert "| b | reached 6/6 in 400 s | 200 / 100 / 300 | 2.00x | **1.50x** | 4 |" in out
    assert "ratio over 1 arenas whole: median 1.50x (range 1.50-1.50x), 0 at 2.5x or more" in out
