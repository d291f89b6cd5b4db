"""The simulated rover's body, motors and sensors.

- Drive: two wheels, each following its PWM command through a dead band and a first-order
  lag, the right motor stronger than the left (the seed compensated with a 0.8 bias), a little
  speed noise; a differential-drive kinematic model (its track: protocol/vehicle.toml).
- Gyro: an MPU6050's yaw rate with white noise and a slowly drifting bias, left over after the
  start-up calibration.
- Sonar: an HC-SR04 on a servo: the nearest echo inside its 15-degree cone, range noise, and
  floor echoes beyond about 0.65 m, as the seed saw. Smooth flat faces (boxes, walls, the arena's
  wall) reflect the 40 kHz burst like a mirror: a face met more than `sonar_max_incidence_deg`
  (40°) off its normal sends it away and gives no echo; posts (cylinders) always echo, and so does
  a corner inside the cone (see rovernav.sim.world). 40° is a modelling choice, not a measured
  constant: a mirror-like echo returns while the reflected burst still falls on the receiver,
  which takes a sound lobe spread well beyond the 15° "measuring angle" the makers quote (their
  detection plots reach about 15-20° either side), and users report canted walls going silent
  from somewhere about 45°; 40° sits a little on the pessimistic side of that. Set it to 90 for
  the old model (every ray that meets a surface echoes).
- Servo: travels at 0.1 s per 60 degrees; the sonar points where the servo is, not where it was
  told to be.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..angles import wrap_deg
from ..link.messages_gen import PARAMS, Param
from ..mapping.sonar_map import sonar_origin
from ..planning.config import geometry_m
from ..vehicle_gen import SONAR_MAX_RANGE_MM, WHEEL_TRACK_MM
from .world import World


@dataclasses.dataclass(frozen=True)
class PlantConfig:
    mm_s_per_pwm: float = 2.2  # wheel speed per PWM above the dead band (firmware assumes 2.0)
    deadband_pwm: float = float(PARAMS[Param.MOTOR_DEADBAND_PWM].default)  # as the firmware assumes
    lag_s: float = 0.08  # motor and inertia
    right_gain: float = 1.10  # the right motor is the stronger
    track_m: float = WHEEL_TRACK_MM / 1000.0  # distance between the wheels (protocol/vehicle.toml)
    speed_noise: float = 0.02  # relative, slowly varying (floor, battery)
    gyro_noise_dps: float = 0.05  # white noise of one sample
    gyro_bias_dps: float = 0.05  # bias left after calibration (one sigma)
    gyro_bias_walk_dps_per_sqrt_s: float = 0.005
    gyro_scale: float = 1.0  # the gyro's reading per true rate (an MPU6050's sensitivity: +-3 %)
    sonar_cone_deg: float = PARAMS[Param.SONAR_CONE_CDEG].default / 100.0
    sonar_noise_mm: float = 3.0
    sonar_floor_m: float = 0.65  # floor echoes from beyond here
    sonar_max_m: float = SONAR_MAX_RANGE_MM / 1000.0  # the driver's last echo (protocol/vehicle.toml): past it, none
    sonar_max_incidence_deg: float = 40.0  # a flat face further off its normal gives no echo (90: always)
    sonar_rays: int = 7  # rays sampled across the cone
    sonar_offset_m: float = geometry_m(Param.SONAR_OFFSET_MM)  # the sensor sits ahead of the rover's centre
    servo_deg_per_s: float = 600.0  # 0.1 s per 60 degrees
    # Wiring faults, for `rovernav check` to find: a motor whose two wires are swapped turns the
    # other way; a ranger with TRIG and ECHO swapped (or unpowered) never answers.
    left_motor_reversed: bool = False
    sonar_connected: bool = True


class RoverPlant:
    """State: pose (x, y in metres, heading in degrees), wheel speeds, servo angle, gyro bias."""

    def __init__(self, x_m: float, y_m: float, heading_deg: float, config: PlantConfig, rng: np.random.Generator):
        self.x, self.y, self.heading = x_m, y_m, heading_deg
        self.cfg = config
        self.rng = rng
        self.v_left = self.v_right = 0.0  # m/s
        self.rate_dps = 0.0
        self.servo_deg = 0.0
        self.gyro_bias = float(rng.normal(0.0, config.gyro_bias_dps))
        self.speed_factor = 1.0
        self.distance_m = 0.0
        self.gyro_alive = True

    def _wheel_target(self, pwm: float, gain: float) -> float:
        m = abs(pwm) - self.cfg.deadband_pwm
        if m <= 0:
            return 0.0
        return math.copysign(m * self.cfg.mm_s_per_pwm * gain / 1000.0, pwm)

    def step(self, left_pwm: int, right_pwm: int, servo_cdeg: int, dt_s: float) -> None:
        c = self.cfg
        k = dt_s / (c.lag_s + dt_s)
        self.speed_factor += 0.02 * (1.0 - self.speed_factor) + c.speed_noise * 0.1 * float(self.rng.normal())
        left = -left_pwm if c.left_motor_reversed else left_pwm
        self.v_left += k * (self._wheel_target(left, 1.0) * self.speed_factor - self.v_left)
        self.v_right += k * (self._wheel_target(right_pwm, c.right_gain) * self.speed_factor - self.v_right)
        v = 0.5 * (self.v_left + self.v_right)
        omega = (self.v_left - self.v_right) / c.track_m  # rad/s, clockwise
        self.rate_dps = math.degrees(omega)
        mid = math.radians(self.heading + 0.5 * self.rate_dps * dt_s)
        self.x += v * dt_s * math.sin(mid)
        self.y += v * dt_s * math.cos(mid)
        self.heading = wrap_deg(self.heading + self.rate_dps * dt_s)
        self.distance_m += abs(v) * dt_s
        # servo
        target = servo_cdeg / 100.0
        step = c.servo_deg_per_s * dt_s
        self.servo_deg += max(-step, min(step, target - self.servo_deg))
        self.gyro_bias += c.gyro_bias_walk_dps_per_sqrt_s * math.sqrt(dt_s) * float(self.rng.normal())

    def gyro_mdps(self) -> int | None:
        """One gyro sample (millidegrees/s, clockwise), or None when the gyro is dead."""
        if not self.gyro_alive:
            return None
        reading = (
            self.rate_dps * self.cfg.gyro_scale + self.gyro_bias + self.cfg.gyro_noise_dps * float(self.rng.normal())
        )
        return int(round(reading * 1000))

    def sonar_mm(self, world: World) -> int:
        """One ping: the nearest surface in the cone (mm), a floor echo, or 0 for nothing."""
        c = self.cfg
        if not c.sonar_connected:
            return 0
        sx, sy = sonar_origin(self.x, self.y, self.heading, c.sonar_offset_m)
        axis = self.heading + self.servo_deg
        nearest = world.sonar_m(sx, sy, axis, c.sonar_cone_deg, c.sonar_max_m, c.sonar_max_incidence_deg, c.sonar_rays)
        if nearest > c.sonar_floor_m:
            # Beyond about 0.65 m the cone reaches the floor: an echo from there, a little random.
            nearest = c.sonar_floor_m + abs(float(self.rng.normal(0.0, 0.05)))
        if nearest >= c.sonar_max_m:
            return 0
        return max(20, int(round(nearest * 1000 + float(self.rng.normal(0.0, c.sonar_noise_mm)))))
