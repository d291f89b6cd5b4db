"""What the host saw of one calibration run, and what each run measures: its steady speed and
commands, the gyro's scale over a turn and its bias over the still window, the sonar's offset
from a sweep facing a wall (the method: rovernav.calibrate.rover's docstring).
"""

from __future__ import annotations

import dataclasses
import math
import statistics

from ...angles import wrap_deg
from ...link import messages_gen as mg
from ...vehicle_gen import SONAR_CONE_CDEG

#: The ranger's beam width [degrees] (protocol/vehicle.toml: sonar_cone_cdeg).
CONE_DEG = SONAR_CONE_CDEG / 100.0

#: The steady part of a run: after the motors' lag and the heading settling, before the slowing
#: for the waypoint.
TRIM_START_S = 0.5
TRIM_END_S = 0.15
#: A run needs this long a steady part and this many camera positions in it.
MIN_STEADY_S = 0.8
MIN_POSES = 15
#: How long one run may take [s] (at 40 mm/s, 0.5 m takes 13 s, and the turn round a few).
RUN_TIME_S = 45.0
#: The gyro's bias: before the first run's START the rover stands still this long with no fix
#: sent [s], from STILL_LEAD_S after its first fix (its heading set by the camera's, which it
#: does not integrate before); the heading's drift is read from BIAS_SKIP_S in (the last fix
#: taken) to the window's end.
STILL_S = 8.0
STILL_LEAD_S = 0.5
BIAS_SKIP_S = 0.5
#: The camera seeing the rover turn more than this [deg] in the still window: it was not still.
STILL_TURN_DEG = 1.0
#: A bias left beyond this [deg/s] is worth a word (the MPU6050's start-up measure leaves ~0.1).
BIAS_WARN_DPS = 0.5
#: The sonar's wall: the rover must face it within this [deg] (drive.py: where it stands).
WALL_FACING_DEG = 30.0
#: An echo counts when its beam's axis is within this of square to the wall [deg] (the HC-SR04's
#: cone is 15 degrees wide: the nearest point of the wall is then in it).
SQUARE_DEG = 6.0


class CalibrationFailed(Exception):
    """The runs did not give what the fit needs (the reason, in one line)."""


@dataclasses.dataclass
class Run:
    """What the host saw of one run: camera poses (t, x, y, heading) and STATUS (t, state, left,
    right, heading_cdeg). A run that begins with a turn (turn_first) has no fixes sent while it
    turns, so that the rover's heading there is its gyro's alone (gyro_scale)."""

    level_pwm: int
    start: tuple[float, float]
    goal: tuple[float, float]
    turn_first: bool = False
    swept: bool = False  # begins with a sweep, facing the wall (for the sonar's offset)
    still_s: float = 0.0  # the still window before START (the first run: STILL_S)
    poses: list[tuple[float, float, float, float]] = dataclasses.field(default_factory=list)
    status: list[tuple[float, int, int, int, int]] = dataclasses.field(default_factory=list)
    echoes: list[tuple[float, float, float]] = dataclasses.field(default_factory=list)  # t, bearing deg, range m
    start_sent_s: float | None = None  # when the host first sent START
    fixed_at_s: float | None = None  # the first STATUS that says the rover has had a fix
    error: str | None = None
    on_status_hooks: list = dataclasses.field(default_factory=list, repr=False)
    true_bias: list[tuple[float, float]] = dataclasses.field(default_factory=list)  # sim only: t, deg/s

    @property
    def time_limit_s(self) -> float:
        """How long the run may take: RUN_TIME_S, and its still window's time."""
        return RUN_TIME_S + (self.still_s + 2 * STILL_LEAD_S if self.still_s > 0 else 0.0)

    def still_window(self) -> tuple[float, float] | None:
        """The still window (start, end) [s], once the rover has had its first fix."""
        if self.still_s <= 0 or self.fixed_at_s is None:
            return None
        t0 = self.fixed_at_s + STILL_LEAD_S
        return t0, t0 + self.still_s

    def hold_start(self, now_s: float) -> bool:
        """Whether START is to wait: a run with a still window sends it once the window is over."""
        if self.still_s <= 0:
            return False
        window = self.still_window()
        return window is None or now_s < window[1]

    def withhold(self, now_s: float) -> bool:
        """Whether a camera fix is to be kept from the rover now: in the still window (its heading
        its gyro's alone, for the bias), and in a turn_first run from the host's START (the rover
        still, its heading fused with the camera's) until the rover reports DRIVE (the turn
        done)."""
        window = self.still_window()
        if window is not None and window[0] <= now_s < window[1]:
            return True
        if not self.turn_first or self.start_sent_s is None:
            return False
        return not any(s[1] == mg.RoverState.DRIVE and s[0] > self.start_sent_s for s in self.status)

    def gyro_bias(self) -> tuple[float, float] | str | None:
        """(bias, its standard error) [deg/s, clockwise] from the still window: the slope of the
        heading the rover reports; or why not (the camera saw the rover turn: it was not still;
        too few reports); None without a still window. The camera's headings are the check that
        the rover stood still, not subtracted: their noise over a few seconds is larger than the
        bias's error."""
        window = self.still_window()
        if window is None:
            return None
        t0, t1 = window[0] + BIAS_SKIP_S, window[1]
        rover = _unwrapped([(s[0], s[4] / 100.0) for s in self.status if t0 <= s[0] <= t1])
        if len(rover) < 10 or rover[-1][0] - rover[0][0] < 0.5 * (t1 - t0):
            return f"the rover reported its heading {len(rover)} times in the {self.still_s:g} s it stood still"
        first = [p[3] for p in self.poses if t0 <= p[0] <= t0 + 1.0]
        last = [p[3] for p in self.poses if t1 - 1.0 <= p[0] <= t1]
        if len(first) < 5 or len(last) < 5:
            return "the camera did not see the rover while it stood still"
        turned = wrap_deg(_circular_median(last) - _circular_median(first))
        if abs(turned) > STILL_TURN_DEG:
            return (
                f"the camera saw the rover turn {turned:+.1f} degrees while it was to stand still "
                "(was it pushed, or its wheels not stopped?)"
            )
        return _slope_se(rover)

    def sonar_offsets(self, wall: tuple[float, float, float, float], cone_deg: float = CONE_DEG) -> list[float] | str:
        """The sonar's offset [m] from each echo of this run's sweep square to `wall` (x0, y0, x1,
        y1 of its face), with the rover's centre and heading from the camera while it swept; or
        why none. An echo off the wall's face square to the beam (within SQUARE_DEG, and the
        cone's half-width) gives r = D - offset cos(heading - n): D the centre's distance from the
        face along its normal n."""
        if not self.echoes:
            return "the sweep reported no echo (is the ranger wired, and the wall within 0.5 m?)"
        t0, t1 = self.echoes[0][0] - 0.5, self.echoes[-1][0] + 0.1
        seen = [p for p in self.poses if t0 <= p[0] <= t1]
        if len(seen) < 3:
            return "the camera did not see the rover while it swept"
        x = statistics.median(p[1] for p in seen)
        y = statistics.median(p[2] for p in seen)
        h = _circular_median([p[3] for p in seen])
        geo = wall_geometry(wall, x, y)
        if isinstance(geo, str):
            return geo
        d_m, normal_deg = geo
        facing = math.cos(math.radians(h - normal_deg))
        if facing < math.cos(math.radians(WALL_FACING_DEG)):
            return (
                f"the rover faced {abs(wrap_deg(h - normal_deg)):.0f} degrees off square to the wall "
                f"(it must face it within {WALL_FACING_DEG:.0f})"
            )
        within = min(SQUARE_DEG, cone_deg / 2)
        offsets = [(d_m - r) / facing for _, b, r in self.echoes if abs(wrap_deg(h + b - normal_deg)) <= within]
        return offsets or f"no echo square to the wall (the sweep faced it within {within:.0f} degrees no time)"

    def gyro_scale(self) -> float | None:
        """The rover's turn (its gyro alone, fixes withheld) over the camera's, or None without a
        turn of 90 degrees or more measured whole."""
        if not self.turn_first or self.start_sent_s is None:
            return None
        # From the last report before START (the rover still) to the first DRIVE report after it
        # (the turn settled): at both ends the rover is still, so the camera's and the radio's
        # delays do not matter.
        i = next((k for k in range(len(self.status) - 1, -1, -1) if self.status[k][0] <= self.start_sent_s), None)
        if i is None:
            return None
        j = next((k for k in range(i, len(self.status)) if self.status[k][1] == mg.RoverState.DRIVE), None)
        if j is None:
            return None
        t_a, t_b = self.status[i][0], self.status[j][0]
        rover = sum(wrap_deg((b[4] - a[4]) / 100.0) for a, b in zip(self.status[i:j], self.status[i + 1 : j + 1]))
        # The camera's headings from the last before t_a to the first after t_b, unwrapped, and
        # read at t_a and t_b by interpolation (the rover turns fast: a frame's 33 ms is degrees).
        k0 = next((k for k in range(len(self.poses) - 1, -1, -1) if self.poses[k][0] <= t_a), None)
        k1 = next((k for k, p in enumerate(self.poses) if p[0] >= t_b), None)
        if k0 is None or k1 is None or k1 - k0 < 10:
            return None
        ts, hs = [self.poses[k0][0]], [self.poses[k0][3]]
        for p in self.poses[k0 + 1 : k1 + 1]:
            hs.append(hs[-1] + wrap_deg(p[3] - hs[-1]))
            ts.append(p[0])

        def at(t: float) -> float:
            for q in range(1, len(ts)):
                if ts[q] >= t:
                    f = (t - ts[q - 1]) / (ts[q] - ts[q - 1]) if ts[q] > ts[q - 1] else 1.0
                    return hs[q - 1] + f * (hs[q] - hs[q - 1])
            return hs[-1]

        seen = at(t_b) - at(t_a)
        return rover / seen if abs(seen) >= 90.0 else None

    def steady(self) -> tuple[float, float, float, int] | str:
        """(speed m/s, mean left, mean right, poses used) over the steady part, or why not."""
        drive = [s for s in self.status if s[1] == mg.RoverState.DRIVE]
        if not self.poses:
            return "the camera never found the rover (calibrate the camera first: rovernav calibrate camera)"
        if len(drive) < 2:
            return self.error or "the rover never drove"
        # The longest stretch of DRIVE reports (a run is one stretch; a stop for a reflex splits it).
        stretches, cur = [], [drive[0]]
        for s in drive[1:]:
            if s[0] - cur[-1][0] > 0.5:
                stretches.append(cur)
                cur = []
            cur.append(s)
        stretches.append(cur)
        best = max(stretches, key=lambda st: st[-1][0] - st[0][0])
        t0, t1 = best[0][0] + TRIM_START_S, best[-1][0] - TRIM_END_S
        if t1 - t0 < MIN_STEADY_S:
            return f"it drove steadily for {max(t1 - t0, 0.0):.1f} s only (a run needs {MIN_STEADY_S} s)"
        ux, uy = self.goal[0] - self.start[0], self.goal[1] - self.start[1]
        n = math.hypot(ux, uy)
        ux, uy = ux / n, uy / n
        pts = [(t, (x - self.start[0]) * ux + (y - self.start[1]) * uy) for t, x, y, _ in self.poses if t0 <= t <= t1]
        if len(pts) < MIN_POSES:
            return f"the camera saw the rover {len(pts)} times while it drove (a run needs {MIN_POSES})"
        speed = slope(pts)
        cmds = [s for s in best if t0 <= s[0] <= t1] or best
        # The mean, not the median: a command is whole PWM, and the PID dithers it by one round a
        # fraction the mean keeps (the balance is a few PWM in 25-70 above the dead band).
        return speed, statistics.fmean(c[2] for c in cmds), statistics.fmean(c[3] for c in cmds), len(pts)


def _unwrapped(pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """(t, heading deg) with the jumps of a turn across +-180 taken out."""
    out: list[tuple[float, float]] = []
    for t, h in pts:
        out.append((t, h if not out else out[-1][1] + wrap_deg(h - out[-1][1])))
    return out


def _circular_median(headings_deg: list[float]) -> float:
    ref = headings_deg[0]
    return wrap_deg(ref + statistics.median(wrap_deg(h - ref) for h in headings_deg))


def _slope_se(pts: list[tuple[float, float]]) -> tuple[float, float]:
    """A least-squares line's slope and its standard error."""
    n = len(pts)
    k = slope(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    resid = sum((p[1] - my - k * (p[0] - mx)) ** 2 for p in pts)
    return k, math.sqrt(resid / max(n - 2, 1) / sxx) if sxx > 0 else math.inf


def wall_geometry(wall: tuple[float, float, float, float], x_m: float, y_m: float) -> tuple[float, float] | str:
    """(distance from (x_m, y_m) to the wall's face line, the direction of its normal towards
    the face [deg, 0 = +y, clockwise]), or why the point is not in front of the face."""
    x0, y0, x1, y1 = wall
    length = math.hypot(x1 - x0, y1 - y0)
    if length < 0.05:
        return "the wall's two ends are the same point"
    ux, uy = (x1 - x0) / length, (y1 - y0) / length
    along = (x_m - x0) * ux + (y_m - y0) * uy
    if not 0.0 <= along <= length:
        return "the rover is not in front of the wall (past one of its ends)"
    across = -(x_m - x0) * uy + (y_m - y0) * ux  # the rover's side of the line
    nx, ny = (uy, -ux) if across > 0 else (-uy, ux)  # towards the face
    return abs(across), math.degrees(math.atan2(nx, ny))


def slope(pts: list[tuple[float, float]]) -> float:
    """A least-squares line's slope."""
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx > 0 else 0.0
