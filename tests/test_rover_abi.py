"""The firmware core through its C ABI, driven from Python over the real protocol.

A small kinematic plant closes the loop; the host side speaks only in frames (HELLO, PATH,
START, FIX) and reads only frames (ACK, EVENT, STATUS).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rovernav.angles import heading_cdeg
from rovernav.cores.native import NativeCore, build_library
from rovernav.link import framing
from rovernav.link import messages_gen as mg
from rovernav.link.link import host_hello
from rovernav.sim.plant import PlantConfig, RoverPlant

#: The rover's arrival radius (the protocol's default): it stops within this of its last waypoint.
ARRIVAL_MM = mg.PARAMS[mg.Param.ARRIVAL_RADIUS_MM].default


@pytest.fixture(scope="module", autouse=True)
def library():
    return build_library()


def ideal_plant(x_mm=300.0, y_mm=300.0, heading_deg=0.0) -> RoverPlant:
    """The simulator's plant (rovernav.sim.plant), with no noise, no bias and motors as the
    firmware's speed model assumes them (its default speed per PWM, equal motors)."""
    cfg = PlantConfig(
        mm_s_per_pwm=mg.PARAMS[mg.Param.SPEED_MM_S_PER_PWM_X1000].default / 1000.0,
        deadband_pwm=float(mg.PARAMS[mg.Param.MOTOR_DEADBAND_PWM].default),
        right_gain=1.0,
        speed_noise=0.0,
        gyro_noise_dps=0.0,
        gyro_bias_dps=0.0,
        gyro_bias_walk_dps_per_sqrt_s=0.0,
    )
    return RoverPlant(x_mm / 1000, y_mm / 1000, heading_deg, cfg, np.random.default_rng(0))


class Host:
    def __init__(self):
        self.seq = 0
        self.decoder = framing.FrameDecoder()
        self.outbox = bytearray()
        self.heard: list = []

    def send(self, message):
        self.outbox += framing.encode_frame(message, self.seq)
        self.seq = (self.seq + 1) & 0xFF

    def take(self, n=57):
        chunk, self.outbox = bytes(self.outbox[:n]), self.outbox[n:]
        return chunk

    def hear(self, data):
        self.heard += [f.message for f in self.decoder.feed(data)]

    def events(self, kind):
        return [m for m in self.heard if isinstance(m, mg.Event) and m.kind == kind]


def test_library_reports_our_schema_and_boots_with_hello():
    core = NativeCore(boot_id=77)
    out = core.step(0, gyro_rate_mdps=0)
    frames = framing.FrameDecoder().feed(out.tx)
    hello = frames[0].message
    assert isinstance(hello, mg.Hello)
    assert hello.schema_hash == mg.SCHEMA_HASH and hello.boot_id == 77 and hello.role == mg.Role.ROVER


def test_python_drives_the_core_through_a_waypoint_list_to_arrival():
    core, plant, host = NativeCore(boot_id=5), ideal_plant(), Host()
    waypoints = [(300, 300), (300, 700), (700, 900), (900, 500)]
    host.send(host_hello(1))
    host.send(mg.Config(param=mg.Param.SWEEP_INTERVAL_MM, value=0))
    xs = tuple(w[0] for w in waypoints) + (0,) * 4
    ys = tuple(w[1] for w in waypoints) + (0,) * 4
    host.send(mg.Path(path_id=3, total=4, first_index=0, count=4, x_mm=xs, y_mm=ys))
    started = False
    now = 0
    arrived_ms = None
    for _ in range(9000):  # at most 90 s
        if now % 33 < 10:
            host.send(
                mg.Fix(
                    x_mm=round(plant.x * 1000),
                    y_mm=round(plant.y * 1000),
                    heading_cdeg=heading_cdeg(plant.heading),
                    sd_mm=2,
                )
            )
        if not started and any(isinstance(m, mg.Event) and m.kind == mg.EventKind.PATH_ACCEPTED for m in host.heard):
            host.send(mg.Start(path_id=3))
            started = True
        out = core.step(now, gyro_rate_mdps=plant.gyro_mdps(), rx=host.take())
        host.hear(out.tx)
        plant.step(out.left_pwm, out.right_pwm, out.servo_cdeg, 0.01)
        now += 10
        if arrived_ms is None and host.events(mg.EventKind.ARRIVED):
            arrived_ms = now
        if arrived_ms is not None and now >= arrived_ms + 1000:
            break  # after arrival, STATUS has gone out again
    assert host.events(mg.EventKind.ARRIVED), "the rover never arrived"
    assert [e.arg for e in host.events(mg.EventKind.WAYPOINT_REACHED)] == [0, 1, 2, 3]
    assert math.hypot(plant.x * 1000 - 900, plant.y * 1000 - 500) < ARRIVAL_MM + 10
    nacks = [m for m in host.heard if isinstance(m, mg.Nack)]
    assert nacks == []
    statuses = [m for m in host.heard if isinstance(m, mg.Status)]
    assert statuses and statuses[-1].state == mg.RoverState.ARRIVED
    probe = core.probe()
    assert abs(probe.x_mm - plant.x * 1000) < 10 and abs(probe.y_mm - plant.y * 1000) < 10


def test_more_bytes_than_the_rover_holds_are_dropped_and_counted():
    # As on the Uno, whose serial buffer drops what comes while it is full.
    core = NativeCore()
    core.step(0, gyro_rate_mdps=0, rx=bytes(300))
    assert core.rx_dropped == 300 - NativeCore.RX_HELD_MAX


def test_a_wrong_key_length_is_refused_clearly():
    with pytest.raises(ValueError, match="16 bytes"):
        NativeCore(key=bytes(5))


def test_the_python_structs_are_checked_against_the_librarys_layout():
    import ctypes

    from rovernav.cores.abi_gen import RoverProbe
    from rovernav.cores.native import STRUCTS, FirmwareBuildError, check_layout, load_library

    lib = load_library()
    check_layout(lib)  # the generated copies agree (load_library checks this too)

    class Probe(ctypes.Structure):  # as if the library had been built with a field that abi_gen.py lacks
        _c_name_ = "rover_probe"
        _fields_ = [
            ("state", ctypes.c_uint8),
            ("fault", ctypes.c_uint8),
            ("flags", ctypes.c_uint32),
        ] + RoverProbe._fields_[3:]

    with pytest.raises(FirmwareBuildError, match=r"sizeof\(rover_probe\) is 32 there, 36 here"):
        check_layout(lib, STRUCTS[:2] + (Probe,))


def test_the_native_core_keeps_the_rover_core_protocol():
    from rovernav.cores import RoverCore

    core = NativeCore()
    assert isinstance(core, RoverCore)
    core.close()
    core.close()  # idempotent, as the protocol says
