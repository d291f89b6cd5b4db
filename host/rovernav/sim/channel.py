"""The radio link in the simulator: bytes at the line rate, with delay, loss, corruption and
outages, in simulated time.

A `Channel` carries one direction. Bytes written at time t leave the sender's queue at the line
rate (57,600 baud 8N1 is 5,760 bytes/s), arrive `delay_s` later, and meanwhile may be dropped or
have a bit flipped. During an outage nothing gets through either way (bytes sent are lost).
`SimTransport` puts a Channel pair behind the host's Transport interface, so the host's Link
runs unchanged.
"""
from __future__ import annotations

import collections
import dataclasses

import numpy as np

from ..link.transport import Transport


@dataclasses.dataclass(frozen=True)
class ChannelConfig:
    baud: int = 57600
    delay_s: float = 0.015          # radio modem latency, one way
    byte_loss: float = 0.0          # probability a byte is lost
    bit_error: float = 0.0          # probability a byte has one bit flipped

    @property
    def bytes_per_s(self) -> float:
        return self.baud / 10.0      # 8N1: ten bits a byte


class Channel:
    """One direction of the radio, in simulated time."""

    def __init__(self, config: ChannelConfig, rng: np.random.Generator, outages: list[tuple[float, float]] = ()):
        self.config = config
        self.rng = rng
        self.outages = list(outages)    # (start_s, end_s)
        self._sending: collections.deque[tuple[float, int]] = collections.deque()  # (written at, byte)
        self._in_flight: collections.deque[tuple[float, int]] = collections.deque()
        self._line_free_at = 0.0
        self.bytes_sent = 0
        self.bytes_delivered = 0
        self.bytes_lost = 0
        self.bytes_corrupted = 0
        self.tap = None   # called with (data, now_s) for every write: an eavesdropper (attacker.py)

    def in_outage(self, t_s: float) -> bool:
        return any(a <= t_s < b for a, b in self.outages)

    def write(self, data: bytes, now_s: float) -> None:
        if self.tap is not None:
            self.tap(data, now_s)
        self._sending.extend((now_s, b) for b in data)
        self.bytes_sent += len(data)

    def queued(self) -> int:
        return len(self._sending)

    def advance(self, now_s: float) -> None:
        """Put on the air every byte the line rate allows up to now."""
        per_byte = 1.0 / self.config.bytes_per_s
        while self._sending:
            written_at, byte = self._sending[0]
            t = max(self._line_free_at, written_at) + per_byte  # when its stop bit is out
            if t > now_s:
                break
            self._sending.popleft()
            self._line_free_at = t
            if self.in_outage(t) or (self.config.byte_loss and self.rng.random() < self.config.byte_loss):
                self.bytes_lost += 1
                continue
            if self.config.bit_error and self.rng.random() < self.config.bit_error:
                byte ^= 1 << int(self.rng.integers(8))
                self.bytes_corrupted += 1
            self._in_flight.append((t + self.config.delay_s, byte))

    def receive(self, now_s: float, max_bytes: int = 1 << 30) -> bytes:
        """The bytes that have arrived by now (at most max_bytes)."""
        self.advance(now_s)
        out = bytearray()
        while self._in_flight and self._in_flight[0][0] <= now_s and len(out) < max_bytes:
            out.append(self._in_flight.popleft()[1])
        self.bytes_delivered += len(out)
        return bytes(out)

    def counters(self) -> dict:
        return {"bytes_sent": self.bytes_sent, "bytes_delivered": self.bytes_delivered,
                "bytes_lost": self.bytes_lost, "bytes_corrupted": self.bytes_corrupted}


class SimTransport(Transport):
    """The host's end of the simulated radio. Reads never wait: simulated time moves only when
    the simulator says so (`set_time`), so a read returns what has arrived by then."""

    def __init__(self, to_rover: Channel, to_host: Channel) -> None:
        super().__init__("simulated radio")
        self.to_rover = to_rover
        self.to_host = to_host
        self.now_s = 0.0

    def set_time(self, now_s: float) -> None:
        self.now_s = now_s

    def _write(self, data: bytes) -> None:
        self.to_rover.write(data, self.now_s)

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        return self.to_host.receive(self.now_s, max_bytes)

    def _close(self) -> None:
        pass
