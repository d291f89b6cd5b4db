"""Moving to a pose (the seed's section 2): the polar transformation, the control law, the kinematics.

Conventions (the report's): x right, y up, metres; θ from the x axis, counter-clockwise, radians.
The goal pose (x*, y*, θ*) need not be the origin.

Which α: the report prints α = atan2(y − y*, x − x*) − θ (eq. 2.3), the bearing *from the goal
to the rover*, but its dynamics (eq. 2.7, ρ̇ = −v cos α) only hold for the bearing *from the
rover to the goal*, atan2(y* − y, x* − x) − θ, which is the printed α with θ + π. Integrated
literally (v = +Kρρ and the printed α) the rover drives away, for ever; reversing into the goal
(v = −Kρρ with the printed α) diverges too from P0, whose printed α is −2.24 rad, outside
(−π/2, π/2]. The rover-to-goal α with v = +Kρρ reproduces the report: P0 → P1 in 3.846 days
(report: 3.85), final error [0.097 m, −5.5e-9 m, 7.8e-7 rad] (report: [8.71e-2, 2.21e-9,
8.47e-7]). That is the reading used here (`to_polar`).

The printed inverse (eq. 2.4, x = −ρ cos(α + β) + x*) does not invert eq. 2.3 either; the
inverse of the transformation used here is x = x* − ρ cos(θ* − β), y = y* − ρ sin(θ* − β),
θ = θ* − α − β (`from_polar`).

Stability (Siegwart & Nourbakhsh, the law's source): locally exponentially stable when
Kρ > 0, Kβ < 0 and Kα − Kρ > 0; `PoseGains` refuses gains that break one of these. The strong
condition Kα + 5/3·Kβ − 2/π·Kρ > 0 (α never leaves (−π/2, π/2], so the rover never reverses)
is *not* met by the report's own gains (0.145 − 0.317 − 0.064 = −0.235), so it is checked only
on request (`check(strong=True)`) and reported as `strongly_stable`.
"""

from __future__ import annotations

import array
import dataclasses
import io
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..angles import wrap_rad
from ..control import PoseGains
from ..files import write_atomic
from ..validate import MAX_SIM_STEPS

CURIOSITY_VMAX_M_S = 0.04  # the seed's V_max: 4 cm/s
REPORT_P0 = (42_380.0, 11_590.0, math.pi / 2)  # eq. 2.1 [m, m, rad]
REPORT_P1 = (33_070.0, 19_010.0, math.pi)  # eq. 2.2 [m, m, rad]
REPORT_TIME_S = 3.85 * 86_400.0  # "Time Required: 3.85 days"
MAX_TIME_S = 30 * 86_400.0  # a run gives up after 30 simulated days

# What `rovernav pose` accepts (and why):
MAX_POSE_COORD_M = 100_000.0  # x, y within ±100 km: twice the report's 50 x 35 km crater map, whose
# metres P0, P1 and P2 are in (an arena's limits are far too small here)
MAX_THETA_RAD = 10.0  # |θ| ≤ 10 rad (wrapped to [−π, π) anyway; 90 would be degrees)
MIN_DT_S, MAX_DT_S = 1e-3, 1.0  # the report's step is 1 s; longer steps make the Euler heading
# update overshoot, shorter ones only add work (steps are capped below)
MAX_VMAX_M_S = 10.0  # Curiosity drives at 0.04 m/s; 10 m/s is already a car
MAX_GAIN = 10.0  # |K| ≤ 10 per second: with steps up to 1 s larger gains only overshoot


def wrap_angle(a: float) -> float:
    """`a` [rad] folded into (−π, π], as the rover's pose law wraps it (rovernav.angles.wrap_rad)."""
    return wrap_rad(a)


def to_polar(state: Sequence[float], goal: Sequence[float]) -> tuple[float, float, float]:
    """(x, y, θ) → (ρ [m], α [rad], β [rad]) relative to the goal pose (x*, y*, θ*); α, β in [−π, π).

    α is the bearing of the goal seen from the rover, relative to its heading (see the module's
    note on the report's eq. 2.3); β = −α − θ + θ*.
    """
    x, y, theta = state
    gx, gy, gtheta = goal
    rho = math.hypot(x - gx, y - gy)
    alpha = wrap_angle(math.atan2(gy - y, gx - x) - theta)
    beta = wrap_angle(-alpha - theta + gtheta)
    return rho, alpha, beta


def from_polar(polar: Sequence[float], goal: Sequence[float]) -> tuple[float, float, float]:
    """(ρ, α, β) → (x, y, θ): the inverse of `to_polar` (θ in [−π, π))."""
    rho, alpha, beta = polar
    gx, gy, gtheta = goal
    bearing = gtheta - beta  # direction rover → goal
    return (gx - rho * math.cos(bearing), gy - rho * math.sin(bearing), wrap_angle(gtheta - alpha - beta))


def report_inverse_as_printed(polar: Sequence[float], goal: Sequence[float]) -> tuple[float, float, float]:
    """Eq. 2.4 exactly as printed; kept to show (in the tests) that it does not invert eq. 2.3."""
    rho, alpha, beta = polar
    gx, gy, gtheta = goal
    return (-rho * math.cos(alpha + beta) + gx, -rho * math.sin(alpha + beta) + gy, wrap_angle(-alpha - beta + gtheta))


@dataclasses.dataclass(frozen=True)
class PoseRun:
    """One run of the law. Arrays hold one sample per Euler step, the start included.

    t [s], x [m], y [m], theta [rad], v [m/s], omega [rad/s] (v, ω: the command applied from
    that sample to the next; the last sample's are those that would apply there).
    final_error: [x − x*, y − y*, wrap(θ − θ*)] in m, m, rad.
    converged: ρ and the heading error fell below the tolerances before the time limit.
    """

    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    gains: PoseGains
    vmax_m_s: float
    dt_s: float
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    converged: bool

    @property
    def time_s(self) -> float:
        return float(self.t[-1])

    @property
    def final_error(self) -> list[float]:
        gx, gy, gtheta = self.goal
        return [float(self.x[-1] - gx), float(self.y[-1] - gy), wrap_angle(float(self.theta[-1]) - gtheta)]

    @property
    def path_length_m(self) -> float:
        return float(np.hypot(np.diff(self.x), np.diff(self.y)).sum())


def min_time_s(
    start: Sequence[float], goal: Sequence[float], k_rho: float, vmax: float, dt: float, rho_tol_m: float = 0.1
) -> float:
    """A lower bound on the time [s] `simulate_pose` needs to bring ρ below `rho_tol_m` with steps of `dt`.

    A step moves the rover v·dt at most, v = min(Kρ·ρ, vmax), so ρ' ≥ g(ρ) = ρ − min(Kρ·ρ, vmax)·dt,
    and g is increasing (Kρ·dt < 1): ρ after k steps is at least g applied k times. That count,
    vmax·dt off ρ per step while ρ > vmax/Kρ, then a factor (1 − Kρ·dt) per step, is what this
    returns, times dt (less one step, for rounding). Used to refuse, before any work, runs that
    cannot end within the limits.
    """
    rho = math.hypot(goal[0] - start[0], goal[1] - start[1])
    if rho < rho_tol_m:
        return 0.0
    rho_s = vmax / k_rho  # above it the speed limit binds
    stride = vmax * dt
    steps = 0.0
    if rho > rho_s:
        n1 = math.ceil((rho - rho_s) / stride)
        if rho - n1 * stride < rho_tol_m:  # below the tolerance while still at top speed
            return max(0.0, ((rho - rho_tol_m) / stride - 1.0) * dt)
        steps, rho = float(n1), rho - n1 * stride
    shrink = 1.0 - k_rho * dt
    if shrink > 0.0 and rho >= rho_tol_m:
        steps += math.log(rho / rho_tol_m) / -math.log(shrink)
    elif rho >= rho_tol_m:
        steps += 1.0
    return max(0.0, (steps - 1.0) * dt)


def simulate_pose(
    start: Sequence[float] = REPORT_P0,
    goal: Sequence[float] = REPORT_P1,
    gains: PoseGains | None = None,
    vmax: float = CURIOSITY_VMAX_M_S,
    dt: float = 1.0,
    rho_tol_m: float = 0.1,
    heading_tol_rad: float = 1e-3,
    max_time_s: float = MAX_TIME_S,
    max_steps: int = MAX_SIM_STEPS,
) -> PoseRun:
    """Drive from `start` to `goal` (poses [m, m, rad]) with the law, Euler steps of `dt` [s].

    v = min(Kρ·ρ, vmax); ω = Kα·α + Kβ·β (not limited); ẋ = v cos θ, ẏ = v sin θ, θ̇ = ω.
    Stops when ρ < `rho_tol_m` and |θ − θ*| < `heading_tol_rad`, or after `max_time_s` or
    `max_steps` steps, whichever comes first (then `converged` is False): the work and the
    memory (six float64 series, 48 bytes a step) are bounded whatever the arguments.
    ValueError for unstable gains, a non-finite pose, or a non-positive vmax or dt.
    """
    gains = gains or PoseGains()
    if not (vmax > 0 and math.isfinite(vmax)):
        raise ValueError(f"vmax must be a positive speed [m/s], got {vmax!r}")
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be a positive time step [s], got {dt!r}")
    if not (max_time_s >= 0 and math.isfinite(max_time_s)):
        raise ValueError(f"max_time_s must be a finite time [s], got {max_time_s!r}")
    start = tuple(float(s) for s in start)
    goal = tuple(float(g) for g in goal)
    for name, pose in (("start", start), ("goal", goal)):
        if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
            raise ValueError(f"{name} pose must be three finite numbers (x [m], y [m], theta [rad]), got {pose!r}")
    kr, ka, kb = gains.k_rho, gains.k_alpha, gains.k_beta
    x, y, theta = start[0], start[1], wrap_angle(start[2])
    gx, gy, gtheta = goal
    ts, xs, ys, ths, vs, oms = (array.array("d") for _ in range(6))
    t_add, x_add, y_add, th_add, v_add, om_add = ts.append, xs.append, ys.append, ths.append, vs.append, oms.append
    t = 0.0
    n_max = min(int(math.ceil(max_time_s / dt)), int(max_steps))
    converged = False
    pi, two_pi = math.pi, 2.0 * math.pi
    atan2, hypot, cos, sin = math.atan2, math.hypot, math.cos, math.sin
    for k in range(n_max + 1):
        # to_polar and wrap_angle (rovernav.angles.wrap_rad), inlined (the same operations, so the
        # same numbers): this loop runs up to max_steps times.
        rho = hypot(x - gx, y - gy)
        alpha = pi - (pi - atan2(gy - y, gx - x) + theta) % two_pi
        alpha = alpha if alpha > -pi else alpha + two_pi
        beta = pi - (pi + alpha + theta - gtheta) % two_pi
        beta = beta if beta > -pi else beta + two_pi
        v = min(kr * rho, vmax)
        omega = ka * alpha + kb * beta
        t_add(t)
        x_add(x)
        y_add(y)
        th_add(theta)
        v_add(v)
        om_add(omega)
        if rho < rho_tol_m and abs(wrap_angle(theta - gtheta)) < heading_tol_rad:
            converged = True
            break
        if k == n_max:
            break
        x += v * cos(theta) * dt
        y += v * sin(theta) * dt
        theta = pi - (pi - theta - omega * dt) % two_pi
        theta = theta if theta > -pi else theta + two_pi
        t = (k + 1) * dt
    as_np = lambda a: np.frombuffer(a, dtype=np.float64)  # noqa: E731 - no copy
    return PoseRun(
        start=start,
        goal=goal,
        gains=gains,
        vmax_m_s=float(vmax),
        dt_s=float(dt),
        t=as_np(ts),
        x=as_np(xs),
        y=as_np(ys),
        theta=as_np(ths),
        v=as_np(vs),
        omega=as_np(oms),
        converged=converged,
    )


def save_figure(fig, path: str | os.PathLike, dpi: int) -> None:
    """Render a matplotlib figure as PNG and put it at `path` atomically (never half a file)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    write_atomic(Path(path), buf.getvalue())


PLOT_POINTS = 20_000


def plot_pose(run: PoseRun, path: str | os.PathLike, obstacles: np.ndarray | None = None, scale_m: float = 1.0) -> None:
    """Trajectory (over `obstacles`, a boolean map of `scale_m` m per pixel, when given), v, θ and ω
    against time in days, in one PNG (the report's Figures 1-5)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stride = max(1, len(run.t) // PLOT_POINTS)  # at most ~PLOT_POINTS points a curve (and the last)
    idx = np.r_[np.arange(0, len(run.t), stride), len(run.t) - 1] if stride > 1 else slice(None)
    t, x, y, v, omega = (a[idx] for a in (run.t, run.x, run.y, run.v, run.omega))
    theta = np.unwrap(run.theta)[idx]  # unwrapped before thinning, so no turn is missed
    days = t / 86_400.0
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    ax = axes[0, 0]
    if obstacles is not None:
        ny, nx = obstacles.shape
        ax.imshow(obstacles, origin="lower", cmap="Greys", extent=(0, nx * scale_m / 1e3, 0, ny * scale_m / 1e3))
    ax.plot(x / 1e3, y / 1e3, "b-", lw=1.5, label="trajectory")
    ax.plot(run.start[0] / 1e3, run.start[1] / 1e3, "go", label="start")
    ax.plot(run.goal[0] / 1e3, run.goal[1] / 1e3, "r*", ms=12, label="goal")
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.set_title("Trajectory")
    ax.legend(loc="best")
    if obstacles is None:
        ax.set_aspect("equal", adjustable="datalim")
    axes[0, 1].plot(days, v * 100.0)
    axes[0, 1].set_ylabel("v [cm/s]")
    axes[0, 1].set_title("Velocity")
    axes[1, 0].plot(days, theta)
    axes[1, 0].set_ylabel("θ [rad], unwrapped")
    axes[1, 0].set_title("Heading")
    axes[1, 1].plot(days, omega)
    axes[1, 1].set_ylabel("ω [rad/s]")
    axes[1, 1].set_title("Angular velocity")
    for a in (axes[0, 1], axes[1, 0], axes[1, 1]):
        a.set_xlabel("t [days]")
        a.grid(True, alpha=0.3)
    fig.suptitle(
        f"Moving to a pose: {run.time_s / 86_400:.2f} days, final error "
        f"[{run.final_error[0]:.2e} m, {run.final_error[1]:.2e} m, {run.final_error[2]:.2e} rad]"
    )
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
