"""The fit over the runs: the motors' figures (speed per PWM, dead band, the right motor's
strength), the gyro's scale and bias, the sonar's offset; and writing them into a configuration.
"""

from __future__ import annotations

import dataclasses
import math
import statistics

from ...link import messages_gen as mg
from .runs import CONE_DEG, CalibrationFailed, Run, slope

#: Parameters the fit writes.
WRITES = (mg.Param.SPEED_MM_S_PER_PWM_X1000, mg.Param.MOTOR_DEADBAND_PWM, mg.Param.RIGHT_BIAS_PERMILLE)


@dataclasses.dataclass(frozen=True)
class Fit:
    mm_s_per_pwm: float
    deadband_pwm: float
    right_gain: float
    residual_mm_s: float  # the speed line's RMS residual
    gain_spread: float  # largest minus least g over the runs
    runs: tuple[tuple[int, float, float, float], ...]  # level, speed m/s, left, right
    gyro_scale: float | None = None  # the gyro's turn over the camera's (no parameter takes it)
    gyro_turns: int = 0  # turns it was measured over
    gyro_bias: tuple[float, float] | str | None = None  # deg/s and its standard error (no parameter
    #                                                        takes it); or why not; None: no still window
    sonar: tuple[float, float, int] | str | None = None  # offset m, spread m, echoes; or why not; None: no wall

    def params(self) -> dict[mg.Param, int]:
        """The rover's parameters the fit gives ([rover] table)."""
        return {
            mg.Param.SPEED_MM_S_PER_PWM_X1000: mg.PARAMS[mg.Param.SPEED_MM_S_PER_PWM_X1000].to_raw(self.mm_s_per_pwm),
            mg.Param.MOTOR_DEADBAND_PWM: round(self.deadband_pwm),
            mg.Param.RIGHT_BIAS_PERMILLE: round(mg.PARAMS[mg.Param.RIGHT_BIAS_PERMILLE].scale / self.right_gain),
        }

    def planner(self) -> dict[str, float]:
        """The planner's geometry the fit gives ([planner] table): the sonar's offset, if measured."""
        if isinstance(self.sonar, tuple):
            return {"sonar_offset_m": round(self.sonar[0], 3)}
        return {}


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
        said = (
            f" (every run: {reasons.pop()})"
            if len(reasons) == 1 and len(why) == len(runs)
            else f" ({'; '.join(why)})"
            if why
            else ""
        )
        raise CalibrationFailed("fewer than two runs to fit a line through" + said)
    if len({round(row[2]) for row in rows}) < 2:
        raise CalibrationFailed("the runs' commands were all alike: nothing to fit a line through")
    pts = [(row[2], 1000.0 * row[1]) for row in rows]  # (left PWM, mm/s)
    k = slope(pts)
    if not k > 0:
        seen = ", ".join(f"{row[0]} PWM: {100 * row[1]:.1f} cm/s" for row in rows)
        raise CalibrationFailed(f"the rover went no faster at higher commands ({seen}): are the motors powered?")
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    d = mx - my / k
    if not 0 <= d < min(row[2] for row in rows):
        raise CalibrationFailed(
            f"the speeds put the dead band at {d:.0f} PWM, outside 0 to the least command: "
            "the runs were not steady (a slipping wheel, a rover held back?)"
        )
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
    return Fit(
        k,
        d,
        g,
        resid,
        max(gains) - min(gains),
        tuple(rows),
        statistics.median(scales) if scales else None,
        len(scales),
        bias,
        sonar,
    )


def sonar_offset(
    runs: list[Run],
    wall: tuple[float, float, float, float],
    cone_deg: float = CONE_DEG,
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


def write_params(path, fit_params: dict, planner: dict | None = None) -> None:
    """Put the fitted parameters into FILE's [rover] table, and the planner's geometry (the
    sonar's offset) into its [planner] table (other keys kept; tables made if missing), checked as
    a configuration before it is written."""
    from ..toml_update import load_for_update, table_for_update, write_checked

    doc = load_for_update(path, "rovernav configuration; [rover] motor figures written by `rovernav calibrate rover`")
    table = table_for_update(path, doc, "rover")
    for p, v in fit_params.items():
        table[mg.PARAMS[p].name] = int(v)
    if planner:
        table = table_for_update(path, doc, "planner")
        for k, v in planner.items():
            table[k] = float(v)
    write_checked(path, doc)
