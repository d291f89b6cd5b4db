"""Localisation (the seed's section 4): dead reckoning and an EKF with range-bearing landmarks.

State q = (x [m], y [m], θ [rad]), θ from the x axis, counter-clockwise. Odometry gives, per
step, a distance δd [m] and a turn δθ [rad] with noise v = (ν_d, ν_θ) of covariance V:
    x' = x + (δd + ν_d) cos θ,  y' = y + (δd + ν_d) sin θ,  θ' = θ + δθ + ν_θ       (eq. 4.1)
    P' = Fq P Fqᵀ + Fv V Fvᵀ                                                       (eq. 4.2-4.4)
A landmark at a known (x_lm, y_lm) is seen at range r and bearing β, noise w of covariance W:
    r = √((x_lm − x)² + (y_lm − y)²),  β = atan2(y_lm − y, x_lm − x) − θ               (eq. 4.5)
    K = P Hqᵀ (Hq P Hqᵀ + Hw W Hwᵀ)⁻¹,  q ← q + K (z − h(q)),  P ← (I − K Hq) P       (eq. 4.6-4.10)

A sign in the report's Hq (eq. 4.7) is off: ∂β/∂x is (y_lm − y)/r², not (y − y_lm)/r², as a
finite difference shows (tests/test_study.py). `jacobian_hq` is the derivative of eq. 4.5.
The bearing innovation is wrapped to [−π, π).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .pose import save_figure, wrap_angle

# --- the models ------------------------------------------------------------------------------


def motion(q: np.ndarray, d_m: float, dtheta_rad: float) -> np.ndarray:
    """Eq. 4.1 with the noise folded into `d_m` and `dtheta_rad`."""
    x, y, theta = q
    return np.array([x + d_m * math.cos(theta), y + d_m * math.sin(theta), wrap_angle(theta + dtheta_rad)])


def jacobian_fq(q: np.ndarray, d_m: float) -> np.ndarray:
    """∂f/∂q at v = 0 (eq. 4.3)."""
    theta = q[2]
    return np.array([[1.0, 0.0, -d_m * math.sin(theta)], [0.0, 1.0, d_m * math.cos(theta)], [0.0, 0.0, 1.0]])


def jacobian_fv(q: np.ndarray) -> np.ndarray:
    """∂f/∂v (eq. 4.4)."""
    theta = q[2]
    return np.array([[math.cos(theta), 0.0], [math.sin(theta), 0.0], [0.0, 1.0]])


def observe(q: np.ndarray, landmark: Sequence[float]) -> np.ndarray:
    """Eq. 4.5: (range [m], bearing [rad]) of `landmark` from pose `q`."""
    dx, dy = landmark[0] - q[0], landmark[1] - q[1]
    return np.array([math.hypot(dx, dy), wrap_angle(math.atan2(dy, dx) - q[2])])


def jacobian_hq(q: np.ndarray, landmark: Sequence[float]) -> np.ndarray:
    """∂h/∂q of eq. 4.5 (the report's eq. 4.7 with the sign of ∂β/∂x corrected)."""
    dx, dy = q[0] - landmark[0], q[1] - landmark[1]
    r2 = dx * dx + dy * dy
    r = math.sqrt(r2)
    return np.array([[dx / r, dy / r, 0.0], [-dy / r2, dx / r2, -1.0]])


HW = np.eye(2)  # eq. 4.8: the sensor noise adds straight to (r, β)


def predict(
    q: np.ndarray, P: np.ndarray, d_m: float, dtheta_rad: float, V: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Dead-reckoning step: the state through eq. 4.1, the covariance through eq. 4.2."""
    Fq, Fv = jacobian_fq(q, d_m), jacobian_fv(q)
    return motion(q, d_m, dtheta_rad), Fq @ P @ Fq.T + Fv @ V @ Fv.T


def update(
    q: np.ndarray, P: np.ndarray, z: np.ndarray, landmark: Sequence[float], W: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """EKF correction with one observation `z` = (r, β) of `landmark` (eq. 4.6, 4.9, 4.10)."""
    Hq = jacobian_hq(q, landmark)
    S = Hq @ P @ Hq.T + HW @ W @ HW.T
    K = P @ Hq.T @ np.linalg.inv(S)
    innovation = z - observe(q, landmark)
    innovation[1] = wrap_angle(innovation[1])
    q_new = q + K @ innovation
    q_new[2] = wrap_angle(q_new[2])
    P_new = (np.eye(3) - K @ Hq) @ P
    return q_new, 0.5 * (P_new + P_new.T)


def pose_error(q_true: np.ndarray, q_est: np.ndarray) -> np.ndarray:
    e = q_true - q_est
    e[2] = wrap_angle(e[2])
    return e


def nees(q_true: np.ndarray, q_est: np.ndarray, P: np.ndarray) -> float:
    """Normalised estimation error squared eᵀP⁻¹e: χ²(3) for a consistent filter."""
    e = pose_error(q_true, q_est)
    return float(e @ np.linalg.solve(P, e))


# --- the scenario ----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class LocalisationScenario:
    """A loop driven in fixed steps, a handful of landmarks, and the noise levels (1σ).

    The rover drives `laps` times round a circle of `loop_radius_m` in steps of `step_m`; each
    `observe_every` steps it ranges the nearest landmark within `max_range_m`.
    """

    loop_radius_m: float = 100.0
    step_m: float = 2.0
    laps: int = 2
    landmarks: tuple[tuple[float, float], ...] = (
        (0.0, 0.0),
        (130.0, 0.0),
        (-130.0, 0.0),
        (0.0, 130.0),
        (0.0, -130.0),
        (90.0, 90.0),
    )
    sigma_d_m: float = 0.04  # odometry distance noise per step
    sigma_theta_rad: float = math.radians(0.3)  # odometry turn noise per step
    sigma_r_m: float = 0.3  # range noise
    sigma_b_rad: float = math.radians(0.5)  # bearing noise
    observe_every: int = 10
    max_range_m: float = 120.0
    initial_sigma: tuple[float, float, float] = (0.1, 0.1, math.radians(0.5))

    @property
    def V(self) -> np.ndarray:
        return np.diag([self.sigma_d_m**2, self.sigma_theta_rad**2])

    @property
    def W(self) -> np.ndarray:
        return np.diag([self.sigma_r_m**2, self.sigma_b_rad**2])

    @property
    def P0(self) -> np.ndarray:
        return np.diag(np.square(self.initial_sigma))

    @property
    def n_steps(self) -> int:
        return int(round(self.laps * 2 * math.pi * self.loop_radius_m / self.step_m))

    @property
    def start(self) -> np.ndarray:
        """On the circle's bottom, heading along +x: the loop is driven counter-clockwise."""
        return np.array([0.0, -self.loop_radius_m, 0.0])


@dataclasses.dataclass(frozen=True)
class LocalisationRun:
    """Truth, dead reckoning and EKF over one run; arrays have n_steps + 1 rows (the start first).

    `dr_*` is odometry alone (eq. 4.1-4.4), `ekf_*` adds the landmark updates; `*_P` are
    (n, 3, 3) covariances, `*_nees` the NEES per step; `observed` marks the steps with an update.
    """

    truth: np.ndarray
    dr_q: np.ndarray
    dr_P: np.ndarray
    ekf_q: np.ndarray
    ekf_P: np.ndarray
    dr_nees: np.ndarray
    ekf_nees: np.ndarray
    observed: np.ndarray
    landmarks: np.ndarray

    def position_errors(self, which: str) -> np.ndarray:
        q = self.dr_q if which == "dr" else self.ekf_q
        return np.hypot(self.truth[:, 0] - q[:, 0], self.truth[:, 1] - q[:, 1])

    def summary(self) -> dict:
        dr, ekf = self.position_errors("dr"), self.position_errors("ekf")
        return {
            "dr_final_position_error_m": float(dr[-1]),
            "dr_mean_position_error_m": float(dr.mean()),
            "ekf_final_position_error_m": float(ekf[-1]),
            "ekf_mean_position_error_m": float(ekf.mean()),
            "dr_mean_nees": float(self.dr_nees[1:].mean()),
            "ekf_mean_nees": float(self.ekf_nees[1:].mean()),
            "n_steps": int(len(self.truth) - 1),
            "n_updates": int(self.observed.sum()),
        }


def run_localisation(
    scenario: LocalisationScenario | None = None, rng: np.random.Generator | int | None = 0
) -> LocalisationRun:
    """Simulate the loop once: noisy odometry and observations drawn from `rng` (a Generator or a seed)."""
    sc = scenario or LocalisationScenario()
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    landmarks = np.asarray(sc.landmarks, dtype=np.float64)
    V, W, P0 = sc.V, sc.W, sc.P0
    n = sc.n_steps
    turn = sc.step_m / sc.loop_radius_m  # the commanded turn per step on the circle

    truth = np.empty((n + 1, 3))
    truth[0] = sc.start
    q_init = sc.start + rng.multivariate_normal(np.zeros(3), P0)  # the estimate starts off by a P0 draw
    q_init[2] = wrap_angle(q_init[2])
    dr_q, ekf_q = np.empty((n + 1, 3)), np.empty((n + 1, 3))
    dr_P, ekf_P = np.empty((n + 1, 3, 3)), np.empty((n + 1, 3, 3))
    dr_q[0] = ekf_q[0] = q_init
    dr_P[0] = ekf_P[0] = P0
    observed = np.zeros(n + 1, dtype=np.bool_)
    sd, sth = sc.sigma_d_m, sc.sigma_theta_rad
    for k in range(n):
        truth[k + 1] = motion(truth[k], sc.step_m, turn)
        d_meas = sc.step_m + sd * rng.standard_normal()
        th_meas = turn + sth * rng.standard_normal()
        dr_q[k + 1], dr_P[k + 1] = predict(dr_q[k], dr_P[k], d_meas, th_meas, V)
        q, P = predict(ekf_q[k], ekf_P[k], d_meas, th_meas, V)
        if (k + 1) % sc.observe_every == 0:
            ranges = np.hypot(landmarks[:, 0] - truth[k + 1, 0], landmarks[:, 1] - truth[k + 1, 1])
            i = int(np.argmin(ranges))
            if ranges[i] <= sc.max_range_m:
                z = observe(truth[k + 1], landmarks[i]) + np.array(
                    [sc.sigma_r_m * rng.standard_normal(), sc.sigma_b_rad * rng.standard_normal()]
                )
                z[1] = wrap_angle(z[1])
                q, P = update(q, P, z, landmarks[i], W)
                observed[k + 1] = True
        ekf_q[k + 1], ekf_P[k + 1] = q, P
    dr_nees = np.array([nees(truth[k], dr_q[k], dr_P[k]) for k in range(n + 1)])
    ekf_nees = np.array([nees(truth[k], ekf_q[k], ekf_P[k]) for k in range(n + 1)])
    return LocalisationRun(
        truth=truth,
        dr_q=dr_q,
        dr_P=dr_P,
        ekf_q=ekf_q,
        ekf_P=ekf_P,
        dr_nees=dr_nees,
        ekf_nees=ekf_nees,
        observed=observed,
        landmarks=landmarks,
    )


@dataclasses.dataclass(frozen=True)
class NeesCheck:
    """NEES over a Monte Carlo of `n_runs`: per-step averages over the runs and their χ² band.

    For a consistent 3-state filter n_runs · mean_k ~ χ²(3·n_runs), so the band (`confidence`,
    two-sided) is [χ²⁻¹(a/2; 3N)/N, χ²⁻¹(1 − a/2; 3N)/N]; `inside` is the share of steps whose
    average lies in it, `mean` the average over runs and steps (3 when consistent).
    """

    per_step: np.ndarray
    band: tuple[float, float]
    mean: float
    inside: float
    n_runs: int


def nees_monte_carlo(
    n_runs: int = 20,
    seed: int = 0,
    scenario: LocalisationScenario | None = None,
    which: str = "ekf",
    confidence: float = 0.95,
) -> NeesCheck:
    """Run the scenario `n_runs` times (independent noise) and check the filter's NEES."""
    from scipy.stats import chi2

    if isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer)) or n_runs < 1:
        raise ValueError(f"n_runs must be a whole number of runs >= 1, got {n_runs!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie strictly between 0 and 1, got {confidence!r}")
    seeds = np.random.SeedSequence(seed).spawn(int(n_runs))
    runs = [run_localisation(scenario, np.random.default_rng(s)) for s in seeds]
    values = np.array([r.ekf_nees if which == "ekf" else r.dr_nees for r in runs])[:, 1:]
    per_step = values.mean(axis=0)
    a = 1.0 - confidence
    band = (float(chi2.ppf(a / 2, 3 * n_runs) / n_runs), float(chi2.ppf(1 - a / 2, 3 * n_runs) / n_runs))
    inside = float(np.mean((per_step >= band[0]) & (per_step <= band[1])))
    return NeesCheck(per_step=per_step, band=band, mean=float(per_step.mean()), inside=inside, n_runs=n_runs)


# --- figures ---------------------------------------------------------------------------------


def _ellipse(mean_xy: np.ndarray, P_xy: np.ndarray, k: float = 3.0, n: int = 48) -> np.ndarray:
    """Points of the k-σ ellipse of a 2-D Gaussian."""
    vals, vecs = np.linalg.eigh(P_xy)
    t = np.linspace(0, 2 * math.pi, n)
    circle = np.stack([np.cos(t), np.sin(t)])
    return (vecs @ (k * np.sqrt(np.maximum(vals, 0))[:, None] * circle)).T + mean_xy


def plot_localisation(
    run: LocalisationRun, path: str, nees_check: NeesCheck | None = None, ellipse_every: int = 20
) -> None:
    """Dead reckoning and EKF against truth with 3σ position ellipses, det(P), and NEES (the
    report's Figures 8-11) into one PNG. A 3σ ellipse holds 98.9 % of a 2-D Gaussian."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(16, 9.5))
    steps = np.arange(len(run.truth))
    for row, (name, q, P, ne) in enumerate(
        (("Dead reckoning", run.dr_q, run.dr_P, run.dr_nees), ("EKF", run.ekf_q, run.ekf_P, run.ekf_nees))
    ):
        ax = axes[row, 0]
        ax.plot(run.truth[:, 0], run.truth[:, 1], "k-", lw=1, label="truth")
        ax.plot(q[:, 0], q[:, 1], "b-", lw=1, label=name)
        for k in range(0, len(q), ellipse_every):
            e = _ellipse(q[k, :2], P[k, :2, :2])
            ax.plot(e[:, 0], e[:, 1], "r-", lw=0.6)
        ax.plot([], [], "r-", lw=0.6, label="3σ ellipse")
        ax.plot(run.landmarks[:, 0], run.landmarks[:, 1], "g^", ms=8, label="landmarks")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{name}: trajectory")
        ax.legend(fontsize=8)
        ax = axes[row, 1]
        ax.semilogy(steps, np.linalg.det(P))
        ax.set_xlabel("step")
        ax.set_ylabel("det(P)")
        ax.set_title(f"{name}: det(P)")
        ax.grid(True, alpha=0.3)
        ax = axes[row, 2]
        ax.semilogy(steps[1:], ne[1:], lw=0.6, label=f"NEES (mean {ne[1:].mean():.2f})")
        ax.axhline(3.0, color="k", ls="--", lw=1, label="3 (consistent)")
        ax.set_xlabel("step")
        ax.set_ylabel("NEES")
        ax.set_title(f"{name}: NEES, one run")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    if nees_check is not None:
        ax = axes[1, 2]
        ax.semilogy(
            steps[1:],
            nees_check.per_step,
            "m-",
            lw=1,
            label=f"mean of {nees_check.n_runs} runs ({nees_check.mean:.2f})",
        )
        for b in nees_check.band:
            ax.axhline(b, color="m", ls=":", lw=1)
        ax.legend(fontsize=8)
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=100)  # atomically: never half a PNG
    finally:
        plt.close(fig)
