"""The seed study (Russo 2024): moving to a pose, A* on a crater map, EKF localisation, and the CLI."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from rovernav.planning import NoPathError, OccupancyGrid, plan
from rovernav.study import (
    REPORT_P0,
    REPORT_P1,
    REPORT_P2,
    LocalisationScenario,
    PoseGains,
    crater_map,
    from_polar,
    nees_monte_carlo,
    path_is_clear,
    plan_on_map,
    run_localisation,
    simulate_pose,
    to_polar,
)
from rovernav.study.cli import add_pose_parser, add_study_parser
from rovernav.study.ekf import jacobian_fq, jacobian_fv, jacobian_hq, motion, observe, update
from rovernav.study.pose import REPORT_TIME_S, report_inverse_as_printed, wrap_angle


@pytest.fixture(scope="module")
def report_run():
    return simulate_pose()


# --- moving to a pose ----------------------------------------------------------------------

POSES = [  # (state, goal)
    ((42_380.0, 11_590.0, math.pi / 2), REPORT_P1),
    ((1.0, 2.0, 0.3), (-4.0, 7.0, -2.5)),
    ((0.0, 0.0, 3.0), (5.0, -1.0, 0.0)),
    ((-3.0, 8.0, -1.0), (0.0, 0.0, 0.0)),
]


@pytest.mark.parametrize("state, goal", POSES)
def test_polar_transformation_round_trips(state, goal):
    back = from_polar(to_polar(state, goal), goal)
    assert back[0] == pytest.approx(state[0], abs=1e-6)
    assert back[1] == pytest.approx(state[1], abs=1e-6)
    assert wrap_angle(back[2] - state[2]) == pytest.approx(0.0, abs=1e-12)
    polar = to_polar(state, goal)
    again = to_polar(back, goal)
    assert again == pytest.approx(polar, abs=1e-9)


def test_the_reports_printed_inverse_does_not_invert_its_transformation():
    # Documented in study/pose.py: eq. 2.4 as printed puts the rover elsewhere.
    state, goal = (1.0, 2.0, 0.3), (-4.0, 7.0, -2.5)
    printed = report_inverse_as_printed(to_polar(state, goal), goal)
    assert math.dist(printed[:2], state[:2]) > 1.0


def test_alpha_is_the_goal_bearing_relative_to_the_heading():
    rho, alpha, beta = to_polar((0.0, 0.0, 0.0), (10.0, 0.0, 0.0))  # goal straight ahead
    assert (rho, alpha, beta) == pytest.approx((10.0, 0.0, 0.0))
    rho, alpha, beta = to_polar((0.0, 0.0, math.pi / 2), (10.0, 0.0, 0.0))  # goal on the right
    assert alpha == pytest.approx(-math.pi / 2)


def test_the_law_reaches_p1_from_p0_with_the_reports_gains_in_about_the_reports_time(report_run):
    run = report_run
    assert run.converged
    assert abs(run.time_s - REPORT_TIME_S) <= 0.2 * REPORT_TIME_S
    assert run.time_s / 86_400 == pytest.approx(3.85, abs=0.02)  # measured 3.846 days
    err = run.final_error
    assert math.hypot(err[0], err[1]) < 1.0
    assert abs(err[2]) < 1e-3
    straight = math.dist(REPORT_P0[:2], REPORT_P1[:2])
    assert straight < run.path_length_m < 1.3 * straight
    assert run.v.max() <= 0.04 + 1e-12


def test_speed_is_clamped_and_the_series_line_up(report_run):
    run = report_run
    n = len(run.t)
    assert all(len(a) == n for a in (run.x, run.y, run.theta, run.v, run.omega))
    assert np.all(np.diff(run.t) > 0)
    assert run.v[0] == pytest.approx(0.04)


def test_a_short_manoeuvre_converges_with_other_gains():
    run = simulate_pose((0.0, 0.0, 0.0), (5.0, 3.0, math.pi / 2), PoseGains(0.5, 1.5, -0.3), vmax=0.5, dt=0.01)
    assert run.converged
    assert math.hypot(*run.final_error[:2]) < 0.1


@pytest.mark.parametrize(
    "gains, condition",
    [
        ((0.0, 0.145, -0.19), "K_rho > 0"),
        ((-0.1, 0.145, -0.19), "K_rho > 0"),
        ((0.1, 0.145, 0.0), "K_beta < 0"),
        ((0.1, 0.145, 0.2), "K_beta < 0"),
        ((0.1, 0.05, -0.19), "K_alpha - K_rho > 0"),
    ],
)
def test_unstable_gains_are_refused_naming_the_condition(gains, condition):
    with pytest.raises(ValueError, match=re_escape(condition)):
        PoseGains(*gains)


def test_strong_stability_is_checked_on_request_and_the_reports_gains_fail_it():
    g = PoseGains()
    assert not g.strongly_stable
    with pytest.raises(ValueError, match=re_escape("K_alpha + 5/3 K_beta - 2/pi K_rho > 0")):
        g.check(strong=True)
    PoseGains(3.0, 8.0, -1.5).check(strong=True)  # Siegwart's example gains


def re_escape(s: str) -> str:
    import re

    return re.escape(s)


# --- crater map and A* ---------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crater_map_keeps_p1_p2_free_and_astar_crosses_it_without_touching_a_rim(seed):
    cmap = crater_map(seed)
    assert cmap.obstacles.shape == (700, 1000) and cmap.scale_m == 50.0
    assert cmap.obstacles.mean() > 0.1  # a real obstacle field
    for p in (REPORT_P0[:2], REPORT_P1[:2], REPORT_P2):
        assert cmap.is_free(*p)
    result = plan_on_map(cmap)
    assert result.waypoints[0] == pytest.approx(REPORT_P1[:2]) and result.waypoints[-1] == pytest.approx(REPORT_P2)
    assert result.length_m >= math.dist(REPORT_P1[:2], REPORT_P2) - 1e-6
    assert path_is_clear(cmap, result.waypoints)
    assert not cmap.obstacles[result.cells[:, 1], result.cells[:, 0]].any()
    # Independently: sample every segment at a tenth of a pixel.
    wp = np.asarray(result.waypoints)
    for a, b in zip(wp[:-1], wp[1:]):
        n = int(math.dist(a, b) / 5.0) + 2
        pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
        ix, iy = (pts[:, 0] // 50.0).astype(int), (pts[:, 1] // 50.0).astype(int)
        assert not cmap.obstacles[iy, ix].any()


def test_crater_map_is_reproducible_from_its_seed():
    assert np.array_equal(crater_map(5).obstacles, crater_map(5).obstacles)
    assert not np.array_equal(crater_map(5).obstacles, crater_map(6).obstacles)


def test_a_route_kept_clear_crosses_no_rim():
    run = simulate_pose(dt=10.0)
    route = np.stack([run.x[::4], run.y[::4]], axis=1)
    assert path_is_clear(crater_map(0, keep_clear_path=route), route)


def test_a_walled_off_goal_raises_no_path():
    blocked = np.zeros((50, 50), dtype=bool)
    blocked[:, 25] = True
    with pytest.raises(NoPathError):
        plan(OccupancyGrid.from_layers(blocked, resolution_m=50.0), (100.0, 100.0), (2000.0, 100.0))


# --- EKF -----------------------------------------------------------------------------------


def numeric_jacobian(f, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(len(x)):
        d = np.zeros_like(x)
        d[i] = eps
        diff = (np.asarray(f(x + d)) - np.asarray(f(x - d))) / (2 * eps)
        cols.append(diff)
    return np.stack(cols, axis=1)


STATES = [np.array([1.0, 2.0, 0.3]), np.array([-5.0, 4.0, 2.8]), np.array([10.0, -3.0, -1.9])]


@pytest.mark.parametrize("q", STATES)
def test_motion_jacobians_match_finite_differences(q):
    d, dth = 1.7, 0.05
    assert np.allclose(jacobian_fq(q, d), numeric_jacobian(lambda s: motion(s, d, dth), q), atol=1e-6)
    fv = numeric_jacobian(lambda v: motion(q, d + v[0], dth + v[1]), [0.0, 0.0])
    assert np.allclose(jacobian_fv(q), fv, atol=1e-6)


@pytest.mark.parametrize("q", STATES)
@pytest.mark.parametrize("lm", [(20.0, 15.0), (-30.0, -2.0)])
def test_observation_jacobian_matches_finite_differences(q, lm):
    assert np.allclose(jacobian_hq(q, lm), numeric_jacobian(lambda s: observe(s, lm), q), atol=1e-6)


def test_the_reports_printed_hq_has_the_wrong_sign_on_dbeta_dx():
    q, lm = STATES[0], (20.0, 15.0)
    dx, dy = q[0] - lm[0], q[1] - lm[1]
    printed = dy / (dx * dx + dy * dy)  # eq. 4.7, row 2, column 1
    assert printed == pytest.approx(-numeric_jacobian(lambda s: observe(s, lm), q)[1, 0])


def test_an_update_pulls_the_estimate_toward_the_truth_and_shrinks_p():
    truth = np.array([0.0, 0.0, 0.0])
    q, P = np.array([1.0, -1.0, 0.05]), np.diag([1.0, 1.0, 0.01])
    W = np.diag([0.01, 1e-4])
    for lm in [(20.0, 0.0), (0.0, 20.0), (-15.0, -10.0)]:
        q, P = update(q, P, observe(truth, lm), lm, W)
    assert np.linalg.norm(q[:2]) < 0.2
    assert np.linalg.det(P) < 1e-3 * 0.01


@pytest.fixture(scope="module")
def localisation_run():
    return run_localisation(rng=0)


def test_ekf_position_error_is_far_below_dead_reckonings(localisation_run):
    s = localisation_run.summary()
    assert s["n_updates"] > 20
    assert s["ekf_final_position_error_m"] < s["dr_final_position_error_m"] / 5
    assert s["ekf_mean_position_error_m"] < s["dr_mean_position_error_m"] / 5


def test_det_p_grows_under_dead_reckoning_and_saws_with_the_ekf(localisation_run):
    run = localisation_run
    dr_det = np.linalg.det(run.dr_P)
    assert np.all(np.diff(dr_det) > 0)
    ekf_det = np.linalg.det(run.ekf_P)
    k = np.flatnonzero(run.observed)
    assert np.all(ekf_det[k] < ekf_det[k - 1])  # each update drops it
    assert ekf_det.max() < dr_det[-1] * 1e-3


def test_mean_nees_over_a_monte_carlo_lies_in_the_chi_square_band():
    check = nees_monte_carlo(n_runs=20, seed=1)
    lo, hi = check.band
    assert lo < 3.0 < hi
    assert lo <= check.mean <= hi
    assert check.mean == pytest.approx(3.0, abs=0.5)
    assert check.inside >= 0.85


def test_nees_catches_an_overconfident_filter():
    # A filter told the odometry is 5× better than it is must fail the same check.
    sc = LocalisationScenario(sigma_d_m=0.04, sigma_theta_rad=math.radians(0.3))
    over = LocalisationScenario(sigma_d_m=0.008, sigma_theta_rad=math.radians(0.06))
    runs = []
    for i in range(5):
        rng = np.random.default_rng(100 + i)
        # Draw the noise at the true level, filter with the small V: swap V by subclassing the scenario.
        runs.append(run_localisation(_Mismatched(sc, over), rng))
    assert np.mean([r.ekf_nees[1:].mean() for r in runs]) > 6.0


class _Mismatched(LocalisationScenario):
    """Noise drawn with `true`'s sigmas, the filter given `told`'s V."""

    def __init__(self, true: LocalisationScenario, told: LocalisationScenario):
        import dataclasses

        super().__init__(**{f.name: getattr(true, f.name) for f in dataclasses.fields(true)})
        object.__setattr__(self, "_told_V", told.V)

    @property
    def V(self):
        return self._told_V


# --- CLI -----------------------------------------------------------------------------------


def parse(argv):
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    add_pose_parser(sub)
    add_study_parser(sub)
    return parser.parse_args(argv)


def test_pose_json_gives_time_error_and_length(capsys):
    args = parse(
        [
            "pose",
            "--from",
            "0",
            "0",
            "0",
            "--to",
            "20",
            "10",
            "1.0",
            "--gains",
            "0.3",
            "0.8",
            "-0.15",
            "--vmax",
            "0.5",
            "--dt",
            "0.05",
            "--json",
        ]
    )
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"time_s", "final_error", "path_length_m"}
    assert len(out["final_error"]) == 3 and math.hypot(*out["final_error"][:2]) < 0.1
    assert out["path_length_m"] >= math.hypot(20, 10)
    assert out["time_s"] > math.hypot(20, 10) / 0.5


def test_pose_defaults_are_the_reports_and_print_time_and_error(capsys):
    args = parse(["pose"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "3.846 days" in out and "final state error" in out


@pytest.mark.parametrize(
    "gains, condition", [(["0.1", "0.05", "-0.19"], "K_alpha - K_rho > 0"), (["0.1", "0.145", "0.19"], "K_beta < 0")]
)
def test_pose_with_unstable_gains_exits_2_with_the_reason(capsys, gains, condition):
    args = parse(["pose", "--gains", *gains, "--json"])
    assert args.func(args) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and condition in captured.err


def test_pose_runs_as_a_module(tmp_path):
    import subprocess
    import sys

    png = tmp_path / "pose.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "rovernav.study.cli",
            "pose",
            "--from",
            "0",
            "0",
            "0",
            "--to",
            "3",
            "0",
            "0",
            "--gains",
            "0.5",
            "1.5",
            "-0.3",
            "--vmax",
            "1",
            "--dt",
            "0.01",
            "--json",
            "--plot",
            str(png),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["final_error"][0] == pytest.approx(0.0, abs=0.1)
    assert png.stat().st_size > 10_000
    bad = subprocess.run(
        [sys.executable, "-m", "rovernav.study.cli", "pose", "--gains", "-1", "1", "-1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "K_rho > 0" in bad.stderr


def test_study_writes_the_figures_and_a_summary(tmp_path, capsys):
    args = parse(["study", "--out", str(tmp_path), "--seed", "0", "--runs", "5"])
    assert args.func(args) == 0
    for name in ("pose.png", "crater_plan.png", "localisation.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["navigation"]["converged"] and s["navigation"]["time_days"] == pytest.approx(3.85, abs=0.02)
    assert s["planning"]["clear"] and s["planning"]["pose_trajectory_clear"]
    assert s["planning"]["length_m"] > math.dist(REPORT_P1[:2], REPORT_P2)
    loc = s["localisation"]
    assert loc["ekf_final_position_error_m"] < loc["dr_final_position_error_m"] / 5
    assert loc["mc_nees_band"][0] <= loc["mc_mean_nees"] <= loc["mc_nees_band"][1]
    assert "days" in capsys.readouterr().out
