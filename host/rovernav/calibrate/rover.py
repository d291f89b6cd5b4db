"""`rovernav calibrate rover`: the motors' figures, from straight runs watched by the camera.

The rover drives RUN_M straight, back and forth, once at each drive command in LEVELS_PWM
(its drive_pwm), its sweeps off; between runs it turns round on the spot. From each run's
steady part (the camera's positions while the rover's STATUS says DRIVE, less the first
TRIM_START_S and the last TRIM_END_S) come its speed (a straight line fitted to the distance
along the run against time) and the mean left and right commands. Then

    speed    v = k (left - d)              k: speed per PWM above the dead band d
                                           (a straight line through the runs' (left, v))
    balance  g = (left - d) / (right - d)  the right motor is g times as strong: the heading
                                           PID holds the rover straight, so both wheels turn
                                           at one speed

written as the rover's parameters speed_mm_s_per_pwm_x1000 = 1000 k, motor_deadband_pwm = d
and right_bias_permille = 1000 / g (the right side's share of a heading correction, scaled to
its strength). How sure: the line's residual and the spread of g across the runs.

The gyro's scale is measured, not written: the runs after the first begin with a turn round,
during which no camera fix is sent, so that the rover's heading there is its gyro's alone; its
turn over the camera's is the scale (no parameter takes it: the camera's fixes correct the
heading).

The gyro's bias is measured, not written: before the first run the rover stands still for
STILL_S with no camera fix sent, so that the drift of the heading it reports is its gyro's bias
(less the camera's, which sees the rover still). The firmware measures the bias itself at every
start, the rover still for its first second; what is measured here is what that left, and it
changes from one start to the next, so no parameter takes it: a large one says the rover was
moved in its first second, or the gyro is failing.

The sonar's offset (how far ahead of the rover's centre the ranger sits, the planner's
sonar_offset_m) is measured from a wall at a known place: the rover stands facing it, the first
run begins with a sweep, and each echo whose beam was square to the wall gives the offset as the
distance from the rover's centre (the camera's) to the wall less the range (written, with the
motors' figures). The simulator's bench has such a wall; on the real rover it is --wall.
"""
from __future__ import annotations

import dataclasses
import math
import statistics

from ..angles import wrap_deg
from ..link import messages_gen as mg
from ..vehicle_gen import SONAR_CONE_CDEG

#: The ranger's beam width [degrees] (protocol/vehicle.toml: sonar_cone_cdeg).
CONE_DEG = SONAR_CONE_CDEG / 100.0

#: Drive commands of the runs [PWM], the length of each run [m].
LEVELS_PWM = (60, 80, 105)
RUN_M = 0.5
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
#: The sonar's wall: the rover's centre this far from it in the simulator's bench [m]; on the real
#: rover the sensor must be WALL_RANGE_M from it and the rover face it within WALL_FACING_DEG.
SIM_WALL_M = 0.40
WALL_RANGE_M = (0.15, 0.5)
WALL_FACING_DEG = 30.0
#: An echo counts when its beam's axis is within this of square to the wall [deg] (the HC-SR04's
#: cone is 15 degrees wide: the nearest point of the wall is then in it).
SQUARE_DEG = 6.0
#: What the runs set: sweeps off (a sweep stops the rover), rotate-and-drive, and the level.
RUN_PARAMS = [(mg.Param.SWEEP_INTERVAL_MM, 0), (mg.Param.SWEEP_AT_START, 0), (mg.Param.SWEEP_BEFORE_TURN_DEG, 0),
              (mg.Param.DRIVE_MODE, int(mg.DriveMode.ROTATE_DRIVE))]
#: Parameters the fit writes.
WRITES = (mg.Param.SPEED_MM_S_PER_PWM_X1000, mg.Param.MOTOR_DEADBAND_PWM, mg.Param.RIGHT_BIAS_PERMILLE)


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
    swept: bool = False                  # begins with a sweep, facing the wall (for the sonar's offset)
    still_s: float = 0.0                 # the still window before START (the first run: STILL_S)
    poses: list[tuple[float, float, float, float]] = dataclasses.field(default_factory=list)
    status: list[tuple[float, int, int, int, int]] = dataclasses.field(default_factory=list)
    echoes: list[tuple[float, float, float]] = dataclasses.field(default_factory=list)  # t, bearing deg, range m
    start_sent_s: float | None = None    # when the host first sent START
    fixed_at_s: float | None = None      # the first STATUS that says the rover has had a fix
    error: str | None = None
    on_status_hooks: list = dataclasses.field(default_factory=list, repr=False)
    true_bias: list[tuple[float, float]] = dataclasses.field(default_factory=list)   # sim only: t, deg/s

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
            return (f"the camera saw the rover turn {turned:+.1f} degrees while it was to stand still "
                    "(was it pushed, or its wheels not stopped?)")
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
            return (f"the rover faced {abs(wrap_deg(h - normal_deg)):.0f} degrees off square to the wall "
                    f"(it must face it within {WALL_FACING_DEG:.0f})")
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
        rover = sum(wrap_deg((b[4] - a[4]) / 100.0) for a, b in zip(self.status[i:j], self.status[i + 1:j + 1]))
        # The camera's headings from the last before t_a to the first after t_b, unwrapped, and
        # read at t_a and t_b by interpolation (the rover turns fast: a frame's 33 ms is degrees).
        k0 = next((k for k in range(len(self.poses) - 1, -1, -1) if self.poses[k][0] <= t_a), None)
        k1 = next((k for k, p in enumerate(self.poses) if p[0] >= t_b), None)
        if k0 is None or k1 is None or k1 - k0 < 10:
            return None
        ts, hs = [self.poses[k0][0]], [self.poses[k0][3]]
        for p in self.poses[k0 + 1:k1 + 1]:
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
        speed = _slope(pts)
        cmds = [s for s in best if t0 <= s[0] <= t1] or best
        # The mean, not the median: a command is whole PWM, and the PID dithers it by one round a
        # fraction the mean keeps (the balance is a few PWM in 25-70 above the dead band).
        return speed, statistics.fmean(c[2] for c in cmds), statistics.fmean(c[3] for c in cmds), len(pts)


@dataclasses.dataclass(frozen=True)
class Fit:
    mm_s_per_pwm: float
    deadband_pwm: float
    right_gain: float
    residual_mm_s: float           # the speed line's RMS residual
    gain_spread: float             # largest minus least g over the runs
    runs: tuple[tuple[int, float, float, float], ...]   # level, speed m/s, left, right
    gyro_scale: float | None = None   # the gyro's turn over the camera's (no parameter takes it)
    gyro_turns: int = 0               # turns it was measured over
    gyro_bias: tuple[float, float] | str | None = None   # deg/s and its standard error (no parameter
    #                                                        takes it); or why not; None: no still window
    sonar: tuple[float, float, int] | str | None = None   # offset m, spread m, echoes; or why not; None: no wall

    def params(self) -> dict[mg.Param, int]:
        """The rover's parameters the fit gives ([rover] table)."""
        return {mg.Param.SPEED_MM_S_PER_PWM_X1000: mg.PARAMS[mg.Param.SPEED_MM_S_PER_PWM_X1000].to_raw(self.mm_s_per_pwm),
                mg.Param.MOTOR_DEADBAND_PWM: round(self.deadband_pwm),
                mg.Param.RIGHT_BIAS_PERMILLE: round(mg.PARAMS[mg.Param.RIGHT_BIAS_PERMILLE].scale / self.right_gain)}

    def planner(self) -> dict[str, float]:
        """The planner's geometry the fit gives ([planner] table): the sonar's offset, if measured."""
        if isinstance(self.sonar, tuple):
            return {"sonar_offset_m": round(self.sonar[0], 3)}
        return {}


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
    k = _slope(pts)
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
    across = -(x_m - x0) * uy + (y_m - y0) * ux   # the rover's side of the line
    nx, ny = (uy, -ux) if across > 0 else (-uy, ux)   # towards the face
    return abs(across), math.degrees(math.atan2(nx, ny))


def _slope(pts: list[tuple[float, float]]) -> float:
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx > 0 else 0.0


def fit(runs: list[Run], wall: tuple[float, float, float, float] | None = None, cone_deg: float = CONE_DEG) -> Fit:
    """The motors' figures from the runs (CalibrationFailed says why there are none); the gyro's
    scale and bias; and with `wall` (its face, where the first run swept facing it) the sonar's
    offset."""
    rows, why = [], []
    for r in runs:
        s = r.steady()
        if isinstance(s, str):
            why.append(f"{r.level_pwm} PWM: {s}")
            continue
        speed, left, right, _ = s
        rows.append((r.level_pwm, speed, left, right))
    if len(rows) < 2:
        reasons = {w.split(": ", 1)[1] for w in why}
        said = (f" (every run: {reasons.pop()})" if len(reasons) == 1 and len(why) == len(runs)
                else f" ({'; '.join(why)})" if why else "")
        raise CalibrationFailed("fewer than two runs to fit a line through" + said)
    if len({round(row[2]) for row in rows}) < 2:
        raise CalibrationFailed("the runs' commands were all alike: nothing to fit a line through")
    pts = [(row[2], 1000.0 * row[1]) for row in rows]   # (left PWM, mm/s)
    k = _slope(pts)
    if not k > 0:
        seen = ", ".join(f"{row[0]} PWM: {100 * row[1]:.1f} cm/s" for row in rows)
        raise CalibrationFailed(f"the rover went no faster at higher commands ({seen}): are the motors powered?")
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    d = mx - my / k
    if not 0 <= d < min(row[2] for row in rows):
        raise CalibrationFailed(f"the speeds put the dead band at {d:.0f} PWM, outside 0 to the least command: "
                                "the runs were not steady (a slipping wheel, a rover held back?)")
    resid = math.sqrt(sum((v - k * (x - d)) ** 2 for x, v in pts) / len(pts))
    above = [(row[2] - d, row[3] - d) for row in rows if row[3] - d > 1.0]
    if not above:
        raise CalibrationFailed("the right motor's commands lay inside the dead band: no balance to measure")
    # Pooled: the runs further above the dead band, where a PWM is a smaller share, count more.
    g = sum(a for a, _ in above) / sum(b for _, b in above)
    gains = [a / b for a, b in above]
    scales = [v for v in (r.gyro_scale() for r in runs) if v is not None]
    bias = next((b for b in (r.gyro_bias() for r in runs) if b is not None), None)
    sonar = None if wall is None else sonar_offset([r for r in runs if r.swept], wall, cone_deg)
    return Fit(k, d, g, resid, max(gains) - min(gains), tuple(rows),
               statistics.median(scales) if scales else None, len(scales), bias, sonar)


def sonar_offset(runs: list[Run], wall: tuple[float, float, float, float], cone_deg: float = CONE_DEG,
                 ) -> tuple[float, float, int] | str:
    """(offset m, spread m, echoes used) over the runs that swept facing the wall: the median of
    their echoes' offsets (Run.sonar_offsets); or why not (the first run's reason)."""
    offsets, why = [], []
    for r in runs:
        got = r.sonar_offsets(wall, cone_deg)
        (why.append if isinstance(got, str) else offsets.extend)(got)
    if len(offsets) < 2:
        return why[0] if why else f"{len(offsets)} echo square to the wall (two or more are needed)"
    return statistics.median(offsets), max(offsets) - min(offsets), len(offsets)


def plan_runs(start_xy: tuple[float, float], heading_deg: float, levels=LEVELS_PWM,
              run_m: float = RUN_M) -> list[tuple[int, tuple[float, float], tuple[float, float]]]:
    """(level, start, goal) for each run: ahead from where the rover stands, then back, and so on."""
    h = math.radians(heading_deg)
    a = start_xy
    b = (a[0] + run_m * math.sin(h), a[1] + run_m * math.cos(h))
    out = []
    for i, level in enumerate(levels):
        out.append((level, a, b) if i % 2 == 0 else (level, b, a))
    return out


def check_room(start_xy, heading_deg: float, arena_w_m: float, arena_h_m: float, margin_m: float,
               run_m: float = RUN_M) -> None:
    """CalibrationFailed unless the runs' line lies margin_m inside the arena."""
    (_, a, b) = plan_runs(start_xy, heading_deg, (0,), run_m)[0]
    for x, y in (a, b):
        if not (margin_m <= x <= arena_w_m - margin_m and margin_m <= y <= arena_h_m - margin_m):
            raise CalibrationFailed(f"the runs go from ({a[0]:.2f}, {a[1]:.2f}) to ({b[0]:.2f}, {b[1]:.2f}) m, closer "
                                    f"than {margin_m:.2f} m to the arena's edge: turn the rover to face "
                                    f"{run_m + margin_m:.1f} m of open floor")


def check_wall(wall: tuple[float, float, float, float], x_m: float, y_m: float, heading_deg: float,
               sonar_offset_m: float) -> None:
    """CalibrationFailed unless the rover at (x_m, y_m), heading_deg stands in front of the wall's
    face, facing it within WALL_FACING_DEG, its sensor WALL_RANGE_M from it (by the offset the
    configuration says: the measure is the offset's correction)."""
    geo = wall_geometry(wall, x_m, y_m)
    if isinstance(geo, str):
        raise CalibrationFailed(f"--wall: {geo}: stand the rover facing the wall, in front of it")
    d_m, normal_deg = geo
    off = abs(wrap_deg(heading_deg - normal_deg))
    if off > WALL_FACING_DEG:
        raise CalibrationFailed(f"--wall: the rover faces {off:.0f} degrees off square to the wall (within "
                                f"{WALL_FACING_DEG:.0f}, please: turn it to face the wall)")
    sensor_m = d_m - sonar_offset_m * math.cos(math.radians(off))
    lo, hi = WALL_RANGE_M
    if not lo <= sensor_m <= hi:
        raise CalibrationFailed(f"--wall: the ranger is {sensor_m:.2f} m from the wall (the camera's place for the "
                                f"rover): stand it {lo:.2f}-{hi:.2f} m from the wall")


def run_error(mission, finished: bool) -> str | None:
    """Why a run's mission ended short, in words (None: it reached its goal): a fault the rover
    reports by name first (rovernav check says what to do about it)."""
    code = mission.last_status.fault if mission.last_status is not None else 0
    if code:
        name = mg.FaultCode(code).name.lower() if code in mg.FaultCode._value2member_map_ else f"code {code}"
        return f"the rover reports a fault, {name} (rovernav check names what to fix)"
    if not finished:
        return "the run took longer than it may"
    return None if mission.error is None else f"the run ended: {mission.error}"


def _watch(mission, run: Run, clock) -> None:
    """Notes in `run` what the mission hears and sends: each STATUS (and the run's extra status
    hooks), each echo of a sweep, and when START is first sent; and START waits for the run's
    still window."""
    send, on_status, on_obstacle = mission._send, mission._on_status, mission._on_obstacle

    def sending(message, again: bool = False):
        if isinstance(message, mg.Start) and run.start_sent_s is None:
            run.start_sent_s = clock()
        return send(message, again)

    def status(m):
        run.status.append((clock(), int(m.state), int(m.left_pwm), int(m.right_pwm), int(m.heading_cdeg)))
        if run.fixed_at_s is None and not m.flags & mg.StatusFlag.DEAD_RECKONING:
            run.fixed_at_s = clock()
        for hook in run.on_status_hooks:
            hook(m)
        on_status(m)

    def obstacle(m):
        if m.range_mm:
            run.echoes.append((clock(), m.bearing_cdeg / 100.0, m.range_mm / 1000.0))
        on_obstacle(m)

    mission._send, mission._on_status, mission._on_obstacle = sending, status, obstacle
    mission.hold_start = run.hold_start


# ---------------------------------------------------------------- in the simulator

def sim_bench(config) -> tuple[tuple[float, float], float, tuple[float, float, float, float]]:
    """The simulator's bench: where the rover stands (its centre) and faces, and the wall's face
    (x0, y0, x1, y1) SIM_WALL_M ahead of it, square to it, 0.6 m long: the runs go the other way
    from the arena's middle."""
    w, h = config.arena.width_m, config.arena.height_m
    start = (w / 2 + RUN_M / 2, h / 2)
    face_x = start[0] + SIM_WALL_M
    return start, 90.0, (face_x, h / 2 - 0.3, face_x, h / 2 + 0.3)


def runs_sim(config, setup=None, seed: int = 1, levels=LEVELS_PWM, progress=None) -> list[Run]:
    """The runs against the simulated rover (a set-up's plant, or the usual one), each its own
    simulation of the same rover, as on the real one: the rover stands on the bench (sim_bench)
    facing the wall, still for STILL_S, sweeps, turns round and runs away from the wall; then back,
    from where the last run left it facing (so it turns round first); and so on. In the sim, a
    run's status rows also note the plant's true gyro bias (Run.true_bias), for the tests."""
    from ..scenario import Arena, Mission, Pose, Scenario, Target, Wall
    from ..sim.runner import SimOptions, Simulation

    w, h = config.arena.width_m, config.arena.height_m
    start, facing, face = sim_bench(config)
    thick = 0.02
    wall = Wall(face[0] + thick / 2, face[1], face[2] + thick / 2, face[3], thick)
    runs = []
    plan = plan_runs(start, facing + 180.0, levels)
    for i, (level, a, b) in enumerate(plan):
        heading = facing if i == 0 else math.degrees(math.atan2(a[0] - plan[i - 1][1][0], a[1] - plan[i - 1][1][1]))
        scenario = Scenario(name="calibrate-rover", arena=Arena(w, h), start=Pose(a[0], a[1], heading % 360.0),
                            target=Target(*b), mission=Mission("reach", 1), obstacles=(), walls=(wall,),
                            description="rovernav calibrate rover's run")
        # The runs that begin on the bench (the first and third) begin with a sweep of the wall.
        swept = i % 2 == 0
        extra = [(mg.Param.SWEEP_AT_START, 1)] if swept else []
        cfg = dataclasses.replace(config, rover={**config.rover, **dict(RUN_PARAMS + extra), mg.Param.DRIVE_PWM: level})
        run = Run(level, a, b, turn_first=True, swept=swept, still_s=STILL_S if i == 0 else 0.0)
        sim = Simulation(scenario, SimOptions(seed=seed + i, max_time_s=run.time_limit_s, config=cfg, setup=setup))
        _watch(sim.mission, run, lambda sim=sim: sim.t)
        on_detection = sim.mission.on_detection

        def saw(d, now, run=run, on_detection=on_detection):
            if d.x_m is not None:
                run.poses.append((d.t_s, d.x_m, d.y_m, d.heading_deg))
            if not run.withhold(now):
                on_detection(d, now)

        def truth(m, run=run, sim=sim):
            run.true_bias.append((sim.t, sim.plant.gyro_bias))

        sim.mission.on_detection = saw
        run.on_status_hooks.append(truth)
        sim.run()
        run.error = run_error(sim.mission, sim.outcome != "timeout")
        runs.append(run)
        if progress is not None:
            progress(i + 1, len(levels))
    return runs


# ---------------------------------------------------------------- on the real rover

def runs_hardware(port: str, camera: str | None, config_path: str | None, levels=LEVELS_PWM,
                  progress=None, wall: tuple[float, float, float, float] | None = None) -> list[Run]:
    """The runs on the real rover on `port`, watched by `camera`, one mission a run on one link;
    from where the camera first sees the rover, ahead the way it faces, then back (with `wall`,
    the face of a wall it stands facing: a sweep first, and the runs away from the wall). Every input is
    checked before a device is opened (InputError, exit 2); the parameters the runs change are
    given back, and the rover stopped, at the end."""
    import os
    import time

    from ..config import load_config
    from ..errors import CameraError, InputError
    from ..hardware import _plain_file, _serial_port, camera_source, link_key, open_camera
    from ..link.link import Link
    from ..link.transport import SerialTransport
    from ..mission import Detection
    from ..mission.spec import MissionSpec
    from ..vision import Locator

    _plain_file(config_path, "configuration file")
    cfg = load_config(config_path)
    name, baud = _serial_port(port, cfg, config_path)
    source = camera_source(camera or cfg.camera.source)
    locator = Locator(cfg.vision, cfg.arena.width_m, cfg.arena.height_m)
    key = link_key(cfg, config_path)
    cap = open_camera(source)
    transport = link = None
    runs: list[Run] = []
    try:
        transport = SerialTransport(name, baud)
        link = Link(transport, key=key)
        t0 = time.monotonic()
        first = None
        while time.monotonic() - t0 < 5.0 and first is None:
            ok, frame = cap.read()
            if not ok:
                raise CameraError(f"camera {str(source)!r} delivered no frame")
            first = locator.locate(frame, time.monotonic() - t0).rover
        if first is None:
            raise CameraError("the camera did not find the rover in 5 s: run rovernav calibrate camera first")
        x, y, heading = first
        try:
            if wall is not None:
                check_wall(wall, x, y, heading, cfg.planner.sonar_offset_m)
                heading = (heading + 180.0) % 360.0   # the runs go away from the wall
            check_room((x, y), heading, cfg.arena.width_m, cfg.arena.height_m, cfg.planner.inflation_m + 0.02)
        except CalibrationFailed as exc:
            raise InputError(str(exc)) from None
        for i, (level, a, b) in enumerate(plan_runs((x, y), heading, levels)):
            # With a wall, the runs that begin where the rover stood (the first and third) begin
            # with a sweep of it.
            swept = wall is not None and i % 2 == 0
            run = Run(level, a, b, turn_first=i > 0 or wall is not None, swept=swept,
                      still_s=STILL_S if i == 0 else 0.0)
            extra = [(mg.Param.SWEEP_AT_START, 1)] if swept else []
            params = {**cfg.rover, **dict(RUN_PARAMS + extra), mg.Param.DRIVE_PWM: level}
            spec = MissionSpec.for_run(None, dataclasses.replace(cfg, rover=params), start_xy=a, target_xy=b,
                                       host_boot_id=int.from_bytes(os.urandom(4), "little"))
            mission = spec.build(link, on_event=lambda t, text: None)
            _watch(mission, run, lambda: time.monotonic() - t0)
            started = time.monotonic()
            while not mission.finished and time.monotonic() - started < run.time_limit_s:
                ok, frame = cap.read()
                now = time.monotonic() - t0
                if ok:
                    det = locator.locate(frame, now)
                    if det.rover is not None:
                        run.poses.append((now, *det.rover))
                        if not run.withhold(now):
                            mission.on_detection(Detection(now, *det.rover), now)
                    else:
                        mission.on_detection(Detection(now, None, None, None, det.reason), now)
                mission.tick(now)
            run.error = run_error(mission, mission.finished)
            runs.append(run)
            if progress is not None:
                progress(i + 1, len(levels))
    finally:
        if link is not None:
            restore = [mg.Stop(reason=mg.StopReason.OPERATOR)] + [
                mg.Config(param=int(p), value=int(cfg.rover.get(p, mg.PARAMS[p].default)))
                for p, _ in RUN_PARAMS + [(mg.Param.DRIVE_PWM, 0)]]
            for message in restore:
                try:
                    link.request(message, timeout_s=0.5, retries=3)
                except Exception:   # noqa: BLE001 - the port may be gone; the runs say what was seen
                    pass
        cap.release()
        if transport is not None:
            transport.close()
    return runs


def write_params(path, fit_params: dict, planner: dict | None = None) -> None:
    """Put the fitted parameters into FILE's [rover] table, and the planner's geometry (the
    sonar's offset) into its [planner] table (other keys kept; tables made if missing), checked as
    a configuration before it is written."""
    from .toml_update import load_for_update, table_for_update, write_checked

    doc = load_for_update(path, "rovernav configuration; [rover] motor figures written by `rovernav calibrate rover`")
    table = table_for_update(path, doc, "rover")
    for p, v in fit_params.items():
        table[mg.PARAMS[p].name] = int(v)
    if planner:
        table = table_for_update(path, doc, "planner")
        for k, v in planner.items():
            table[k] = float(v)
    write_checked(path, doc)
