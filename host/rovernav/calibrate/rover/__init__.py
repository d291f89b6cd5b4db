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

The modules, by concern:
    runs      Run: what the host saw of one run, and what each run measures (its steady
              speed and commands, the gyro's scale and bias, the sonar's offsets)
    fitting   Fit and fit: the figures over the runs; write_params puts them in a configuration
    drive     the runs driven: their plan, the rover's place checked, runs_sim and runs_hardware
Their names are all here, as `rovernav calibrate rover` (calibrate/cli_rover.py) uses them.
"""

from .drive import (
    LEVELS_PWM,
    RUN_M,
    RUN_PARAMS,
    SIM_WALL_M,
    WALL_RANGE_M,
    check_room,
    check_wall,
    plan_runs,
    run_error,
    runs_hardware,
    runs_sim,
    sim_bench,
)
from .fitting import WRITES, Fit, fit, sonar_offset, write_params
from .runs import (
    BIAS_SKIP_S,
    BIAS_WARN_DPS,
    CONE_DEG,
    MIN_POSES,
    MIN_STEADY_S,
    RUN_TIME_S,
    SQUARE_DEG,
    STILL_LEAD_S,
    STILL_S,
    STILL_TURN_DEG,
    TRIM_END_S,
    TRIM_START_S,
    WALL_FACING_DEG,
    CalibrationFailed,
    Run,
    wall_geometry,
)

__all__ = [
    "BIAS_SKIP_S",
    "BIAS_WARN_DPS",
    "CONE_DEG",
    "LEVELS_PWM",
    "MIN_POSES",
    "MIN_STEADY_S",
    "RUN_M",
    "RUN_PARAMS",
    "RUN_TIME_S",
    "SIM_WALL_M",
    "SQUARE_DEG",
    "STILL_LEAD_S",
    "STILL_S",
    "STILL_TURN_DEG",
    "TRIM_END_S",
    "TRIM_START_S",
    "WALL_FACING_DEG",
    "WALL_RANGE_M",
    "WRITES",
    "CalibrationFailed",
    "Fit",
    "Run",
    "check_room",
    "check_wall",
    "fit",
    "plan_runs",
    "run_error",
    "runs_hardware",
    "runs_sim",
    "sim_bench",
    "sonar_offset",
    "wall_geometry",
    "write_params",
]
