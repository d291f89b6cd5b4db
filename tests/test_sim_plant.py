"""The simulator's plant: the motors' dead band and lag, the gyro, the servo and the sonar as the
rover's own sensors read them. (Split from test_sim.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rovernav.sim.plant import PlantConfig, RoverPlant
from rovernav.sim.world import Box, Wall, World


def _plant(**kw) -> RoverPlant:
    cfg = PlantConfig(
        **({"speed_noise": 0.0, "gyro_noise_dps": 0.0, "gyro_bias_dps": 0.0, "gyro_bias_walk_dps_per_sqrt_s": 0.0} | kw)
    )
    return RoverPlant(1.0, 1.0, 0.0, cfg, np.random.default_rng(0))


# ---------------------------------------------------------------- plant


def test_plant_speed_follows_pwm_above_the_dead_band_through_a_first_order_lag():
    p = _plant(right_gain=1.0)
    for _ in range(8):  # one lag constant (0.08 s)
        p.step(100, 100, 0, 0.01)
    v_tau = 0.5 * (p.v_left + p.v_right)
    for _ in range(200):
        p.step(100, 100, 0, 0.01)
    v_end = 0.5 * (p.v_left + p.v_right)
    assert v_end == pytest.approx((100 - 30) * 2.2 / 1000, rel=0.01)
    assert 0.55 < v_tau / v_end < 0.7  # 1 - 1/e after one time constant
    assert p.heading == pytest.approx(0.0, abs=1e-6) and p.y > 1.0


def test_plant_does_not_move_inside_the_dead_band():
    p = _plant()
    for _ in range(100):
        p.step(25, -25, 0, 0.01)
    assert (p.x, p.y, p.heading) == (1.0, 1.0, 0.0)


def test_the_stronger_right_motor_turns_the_rover_left_at_equal_commands():
    p = _plant(right_gain=1.10)
    for _ in range(200):
        p.step(80, 80, 0, 0.01)
    assert p.heading < -5.0  # anticlockwise


def test_gyro_reads_the_true_rate_with_noise_and_bias_and_can_die():
    cfg = PlantConfig(gyro_noise_dps=0.05, gyro_bias_dps=0.05)
    p = RoverPlant(1.0, 1.0, 0.0, cfg, np.random.default_rng(4))
    samples = np.array([p.gyro_mdps() for _ in range(2000)]) / 1000
    assert abs(samples.mean() - p.gyro_bias) < 0.005
    assert samples.std() == pytest.approx(0.05, rel=0.1)
    p.gyro_alive = False
    assert p.gyro_mdps() is None


def test_servo_travels_at_0_1_s_per_60_degrees():
    p = _plant()
    steps = 0
    while p.servo_deg > -60.0 + 1e-9:
        p.step(0, 0, -6000, 0.01)
        steps += 1
    assert steps == 10


def test_sonar_sees_the_nearest_surface_inside_its_cone_only():
    world = World(3.0, 3.0, [Box(1.0, 1.4, 0.2, 0.1)])  # face at y = 1.35
    p = _plant(sonar_noise_mm=0.0)
    assert p.sonar_mm(world) == pytest.approx(250, abs=2)  # sensor at y = 1.10
    p.x = 1.0 + 0.1 + 0.25 * math.tan(math.radians(5))  # the box's edge 5 degrees off axis
    assert p.sonar_mm(world) < 400
    p.x = 1.0 + 0.1 + 0.25 * math.tan(math.radians(20))  # well outside the 7.5-degree half cone
    assert p.sonar_mm(world) > 600  # only the floor


def test_sonar_hears_the_floor_beyond_about_0_65_m():
    world = World(5.0, 5.0, [])
    p = _plant()
    p.x, p.y = 2.5, 1.0
    assert 650 <= p.sonar_mm(world) < 900


def test_the_plant_pings_with_the_incidence_limit():
    world = World(4.0, 4.0, [], [Wall(0.2, 2.0, 3.8, 2.0, 0.05)])
    for limit, heard in ((40.0, False), (90.0, True)):
        p = _plant(sonar_noise_mm=0.0, sonar_max_incidence_deg=limit)
        p.x, p.y, p.heading = 1.5, 1.6, 60.0  # the sensor 0.1 m ahead of the centre
        mm = p.sonar_mm(world)
        sy = 1.6 + 0.1 * math.cos(math.radians(60))
        if heard:
            assert mm == pytest.approx((1.975 - sy) / math.cos(math.radians(52.5)) * 1000, abs=1)
        else:
            assert mm >= 650  # only the floor
