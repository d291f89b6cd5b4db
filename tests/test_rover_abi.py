"""The firmware core through its C ABI, driven from Python over the real protocol.

A small kinematic plant closes the loop; the host side speaks only in frames (HELLO, PATH,
START, FIX) and reads only frames (ACK, EVENT, STATUS).
"""
from __future__ import annotations

import math

import pytest

from rovernav.angles import heading_cdeg
from rovernav.firmware import RoverCore, build_library
from rovernav.link import framing
from rovernav.link import messages_gen as mg


@pytest.fixture(scope="module", autouse=True)
def library():
    return build_library()


class Plant:
    """Differential drive with a dead band and a first-order lag; heading clockwise from +y."""

    def __init__(self, x=300.0, y=300.0, heading_deg=0.0):
        self.x, self.y, self.h = x, y, math.radians(heading_deg)
        self.l = self.r = 0.0
        self.rate_dps = 0.0

    @staticmethod
    def eff(pwm):
        return 0.0 if abs(pwm) <= 30 else math.copysign(abs(pwm) - 30, pwm)

    def advance(self, left, right, dt):
        k = dt / (0.08 + dt)
        self.l += k * (self.eff(left) - self.l)
        self.r += k * (self.eff(right) - self.r)
        v = 2.0 * 0.5 * (self.l + self.r)
        self.rate_dps = 1.2 * 0.5 * (self.l - self.r)
        mid = self.h + 0.5 * math.radians(self.rate_dps) * dt
        self.x += v * dt * math.sin(mid)
        self.y += v * dt * math.cos(mid)
        self.h += math.radians(self.rate_dps) * dt


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
    core = RoverCore(boot_id=77)
    out = core.step(0, gyro_rate_mdps=0)
    frames = framing.FrameDecoder().feed(out.tx)
    hello = frames[0].message
    assert isinstance(hello, mg.Hello)
    assert hello.schema_hash == mg.SCHEMA_HASH and hello.boot_id == 77 and hello.role == mg.Role.ROVER


def test_python_drives_the_core_through_a_waypoint_list_to_arrival():
    core, plant, host = RoverCore(boot_id=5), Plant(), Host()
    waypoints = [(300, 300), (300, 700), (700, 900), (900, 500)]
    host.send(mg.Hello(schema_hash=mg.SCHEMA_HASH, boot_id=1, firmware_version=1, role=mg.Role.HOST))
    host.send(mg.Config(param=mg.Param.SWEEP_INTERVAL_MM, value=0))
    xs = tuple(w[0] for w in waypoints) + (0,) * 4
    ys = tuple(w[1] for w in waypoints) + (0,) * 4
    host.send(mg.Path(path_id=3, total=4, first_index=0, count=4, x_mm=xs, y_mm=ys))
    started = False
    now = 0
    for _ in range(9000):  # at most 90 s
        if now % 33 < 10:
            host.send(mg.Fix(x_mm=round(plant.x), y_mm=round(plant.y),
                             heading_cdeg=heading_cdeg(math.degrees(plant.h)),
                             sd_mm=2))
        if not started and any(isinstance(m, mg.Event) and m.kind == mg.EventKind.PATH_ACCEPTED for m in host.heard):
            host.send(mg.Start(path_id=3))
            started = True
        out = core.step(now, gyro_rate_mdps=round(plant.rate_dps * 1000), rx=host.take())
        host.hear(out.tx)
        plant.advance(out.left_pwm, out.right_pwm, 0.01)
        now += 10
        if host.events(mg.EventKind.ARRIVED) and now % 1000 == 0:
            break  # after arrival, one more STATUS has gone out
    assert host.events(mg.EventKind.ARRIVED), "the rover never arrived"
    assert [e.arg for e in host.events(mg.EventKind.WAYPOINT_REACHED)] == [0, 1, 2, 3]
    assert math.hypot(plant.x - 900, plant.y - 500) < 46
    nacks = [m for m in host.heard if isinstance(m, mg.Nack)]
    assert nacks == []
    statuses = [m for m in host.heard if isinstance(m, mg.Status)]
    assert statuses and statuses[-1].state == mg.RoverState.ARRIVED
    probe = core.probe()
    assert abs(probe.x_mm - plant.x) < 10 and abs(probe.y_mm - plant.y) < 10


def test_more_bytes_than_the_rover_holds_are_dropped_and_counted():
    # As on the Uno, whose serial buffer drops what comes while it is full.
    core = RoverCore()
    core.step(0, gyro_rate_mdps=0, rx=bytes(300))
    assert core.rx_dropped == 300 - RoverCore.RX_HELD_MAX


def test_a_wrong_key_length_is_refused_clearly():
    with pytest.raises(ValueError, match="16 bytes"):
        RoverCore(key=bytes(5))
