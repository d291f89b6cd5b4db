"""The simulator's radio channel: line rate and delay, outages, corrupted bits.
(Split from test_sim.py.)"""

from __future__ import annotations

import numpy as np

from rovernav.radio import ChannelConfig
from rovernav.sim.channel import Channel

# ---------------------------------------------------------------- radio


def test_channel_carries_bytes_at_the_line_rate_after_the_delay():
    ch = Channel(ChannelConfig(delay_s=0.015), np.random.default_rng(0))
    ch.write(bytes(576), 0.0)  # 0.1 s of line time at 5,760 bytes/s
    assert ch.receive(0.015) == b""  # nothing before the delay has passed
    early = len(ch.receive(0.05))  # 35 ms of line time: about 201 bytes
    assert 195 <= early <= 203
    assert early + len(ch.receive(0.2)) == 576
    assert ch.receive(1.0) == b""


def test_channel_outage_loses_everything_sent_during_it():
    ch = Channel(ChannelConfig(), np.random.default_rng(0), outages=[(0.0, 1.0)])
    ch.write(b"x" * 100, 0.1)
    assert ch.receive(2.0) == b"" and ch.bytes_lost == 100
    ch.write(b"y" * 10, 1.5)
    assert ch.receive(2.0) == b"y" * 10


def test_channel_corruption_flips_bits():
    ch = Channel(ChannelConfig(bit_error=0.5), np.random.default_rng(1))
    ch.write(bytes(1000), 0.0)
    data = ch.receive(1.0)
    assert len(data) == 1000 and ch.bytes_corrupted == sum(1 for b in data if b)
