"""The radio link in the simulator: bytes at the line rate, with delay, loss, corruption, bursts,
jitter, collisions and outages, in simulated time.

A `Channel` carries one direction. Bytes written at time t leave the sender's queue at the line
rate (57,600 baud 8N1 is 5,760 bytes/s), arrive `delay_s` later, and meanwhile may be dropped or
have a bit flipped. During an outage nothing gets through either way (bytes sent are lost).
`SimTransport` puts a Channel pair behind the host's Transport interface, so the host's Link
runs unchanged; `channel_pair` makes the pair the simulator uses.

What can be set, and what each setting means, is rovernav/radio.py's (`ChannelConfig`,
`radio_config`): the radio's model, below both the configuration and the simulator.

Every feature draws from the simulation's random generator only when it is on: a run with the
defaults makes exactly the draws it made before any of them existed (same seed, same run).

Each Channel also follows the frames its sender writes (COBS-encoded bodies ending in 0x00,
body = version | msg_id | seq | ...): `counters()` gives bytes sent, delivered, lost (by cause)
and corrupted, and per message kind the frames that went on the air and those damaged (any byte
of the frame, its delimiter included, lost or corrupted).
"""

from __future__ import annotations

import collections
import math
from typing import TYPE_CHECKING

from ..link.framing import cobs_decode
from ..link.messages_gen import MESSAGES
from ..link.transport import Transport
from ..radio import ChannelConfig

if TYPE_CHECKING:  # the simulation's generator; this module needs no numpy of its own
    import numpy as np

#: The longest run of bytes without a delimiter the frame counter keeps (longer: "malformed").
_MAX_PARTIAL = 1024
#: Past this many switch times kept, the burst process forgets those every direction has passed.
_PRUNE_EDGES = 4096


# ---------------------------------------------------------------- bursts


class BurstProcess:
    """A two-state (good, burst) Gilbert-Elliott process in simulated time, drawn lazily from the
    simulation's generator: the state at time 0 from the long-run shares, then exponential
    sojourns (mean `mean_s` in a burst, mean_s (1 - share) / share between bursts). Each reader
    (a Channel) asks through its own `view()`, in its own time order; the switch times are kept
    until every view has passed them, so two directions read the same bursts."""

    FORGET_LAG_S = 60.0

    def __init__(self, mean_s: float, share: float, rng: np.random.Generator):
        if not (mean_s > 0 and 0 < share < 1):
            raise ValueError(f"bursts need a mean > 0 and a share in (0, 1), got {mean_s}, {share}")
        self.mean_s, self.share = mean_s, share
        self.mean_good_s = mean_s * (1 - share) / share
        self.rng = rng
        self._bad0: bool | None = None  # the state at time 0 (drawn at the first question)
        self._edges: list[float] = []  # switch times not yet forgotten
        self._base = 0  # absolute index of _edges[0]
        self._last = 0.0  # the last switch time drawn (0: none yet)
        self._dropped_end = 0.0  # the last forgotten switch time
        self._dropped_bursts = 0  # bursts that ended at a forgotten switch, and their time
        self._dropped_burst_s = 0.0
        self._views: list[BurstView] = []

    def view(self) -> BurstView:
        v = BurstView(self)
        self._views.append(v)
        return v

    def _bad_after(self, k: int) -> bool:
        """The state after the first k switches."""
        return self._bad0 ^ bool(k & 1)

    def _passed(self, k: int, t_s: float) -> tuple[int, float]:
        """How many switches there are at or before t_s, counting on from k (those before k are),
        and when the next one is; switch times are drawn as needed."""
        if len(self._edges) > _PRUNE_EDGES:
            self._forget()
        k = max(k, self._base)
        edges = self._edges
        while True:
            i = k - self._base
            if i == len(edges):
                if self._bad0 is None:
                    self._bad0 = bool(self.rng.random() < self.share)
                bad = self._bad_after(k)
                self._last += float(self.rng.exponential(self.mean_s if bad else self.mean_good_s))
                edges.append(self._last)
            if edges[i] > t_s:
                return k, edges[i]
            k += 1

    def _forget(self) -> None:
        """Drop the switch times every view has passed, keeping their totals for stats(). A view
        more than FORGET_LAG_S behind the others is not waited for (a direction that has sent
        nothing for that long): when it asks again it starts from the first switch kept."""
        if not self._views:
            return
        lead = max(v.t for v in self._views)
        cutoff = max(min(v.t for v in self._views), lead - self.FORGET_LAG_S)
        upto = self._base
        while upto - self._base < len(self._edges) - 1 and self._edges[upto - self._base] <= cutoff:
            upto += 1
        for j in range(self._base, upto):
            end = self._edges[j - self._base]
            if self._bad_after(j):  # the interval that ends at switch j
                self._dropped_bursts += 1
                self._dropped_burst_s += end - self._dropped_end
            self._dropped_end = end
        del self._edges[: upto - self._base]
        self._base = upto

    def stats(self, t_s: float) -> dict:
        """Bursts begun by t_s, the time spent in them, and that time's share of [0, t_s] (no draws)."""
        if self._bad0 is None:
            return {"bursts": 0, "burst_time_s": 0.0, "share_measured": 0.0 if t_s > 0 else None}
        bursts, burst_s = self._dropped_bursts, self._dropped_burst_s
        start, k = self._dropped_end, self._base
        for end in self._edges:
            if start >= t_s:
                break
            if self._bad_after(k):
                bursts += 1
                burst_s += min(end, t_s) - start
            start, k = end, k + 1
        else:
            if start < t_s and self._bad_after(k):  # past the last switch drawn
                bursts += 1
                burst_s += t_s - start
        return {
            "bursts": bursts,
            "burst_time_s": round(burst_s, 6),
            "share_measured": round(burst_s / t_s, 6) if t_s > 0 else None,
        }


class BurstView:
    """One reader's place in a BurstProcess: `bad(t)` for nondecreasing t."""

    __slots__ = ("proc", "k", "t", "_next", "_bad")

    def __init__(self, proc: BurstProcess):
        self.proc = proc
        self.k = 0  # switches at or before the last time asked
        self.t = 0.0  # the last time asked
        self._next = -math.inf  # when the state last found ends
        self._bad = False

    def bad(self, t_s: float) -> bool:
        self.t = t_s
        if t_s < self._next:
            return self._bad
        self.k, self._next = self.proc._passed(self.k, t_s)
        self._bad = self.proc._bad_after(self.k)
        return self._bad


# ---------------------------------------------------------------- the shared medium


class Medium:
    """One half-duplex radio medium that every transmitter's Channels share. It puts their bytes on
    the air in the order their stop bits go out, and a byte whose time on the air
    [end - 1/bytes_per_s, end) overlaps one from another transmitter is lost, with that one.

    Two ends (a host and its rover: `channel_pair`), or a fleet's (`fleet_channels`): each
    Channel is one transmitter's bytes to one receiver, and the Channels of one transmitter (the
    host's to each rover, which carry the very same bytes at the same times) are attached with one
    `group` and never collide with each other."""

    def __init__(self) -> None:
        self.ends: list[Channel] = []
        self.groups: list[object] = []

    def attach(self, channel: Channel, group: object = None) -> None:
        """One more end; `group`: the transmitter it shares with the ends attached with the same
        group (None: a transmitter of its own)."""
        self.ends.append(channel)
        self.groups.append(object() if group is None else group)

    def advance(self, now_s: float) -> None:
        ends = self.ends
        if len(ends) == 1:
            ends[0]._advance_alone(now_s)
            return
        if len(ends) == 2:
            self._advance_two(now_s)
            return
        groups = self.groups
        while True:
            # The end whose next stop bit goes out first (the earlier attached on a tie).
            k, start, end = -1, math.inf, math.inf
            for i, e in enumerate(ends):
                s_i = e._next_start()
                t_i = s_i + e._per_byte
                if t_i < end:
                    k, start, end = i, s_i, t_i
            if end > now_s:  # also when every end is idle (inf)
                return
            x, group = ends[k], groups[k]
            # Another transmitter's last byte ended after this one started, or its next starts
            # before this one ends.
            collided = any(
                groups[i] is not group and (y._last_end > start or y._next_start() < end) for i, y in enumerate(ends)
            )
            x._take(end, collided)

    def _advance_two(self, now_s: float) -> None:
        """`advance` for two ends, as it was before fleets (the same draws, the same order)."""
        a, b = self.ends
        same = self.groups[0] is self.groups[1]
        while True:
            sa, sb = a._next_start(), b._next_start()
            ta, tb = sa + a._per_byte, sb + b._per_byte
            if ta <= tb:
                x, y, s, t = a, b, sa, ta
            else:
                x, y, s, t = b, a, sb, tb
            if t > now_s:  # also when both are idle (inf)
                return
            # y's last byte ended after x's started, or y's next starts before x's ends.
            collided = not same and (y._last_end > s or y._next_start() < t)
            x._take(t, collided)


# ---------------------------------------------------------------- one direction


def frame_kind(encoded: bytes) -> str:
    """The message name of a COBS-encoded frame (its delimiter left off), "unknown" for a message
    id the protocol lacks, "malformed" for bytes that are no frame."""
    body = cobs_decode(encoded) if len(encoded) <= _MAX_PARTIAL else None
    if body is None or len(body) < 3:
        return "malformed"
    cls = MESSAGES.get(body[1])
    return cls.NAME if cls is not None else "unknown"


class Channel:
    """One direction of the radio, in simulated time. `bursts`: the BurstProcess it shares with
    the other direction (None: its own when the config has bursts); `medium`: the half-duplex
    Medium it shares (None: its own when the config is half duplex, with no other end)."""

    def __init__(
        self,
        config: ChannelConfig,
        rng: np.random.Generator,
        outages: list[tuple[float, float]] = (),
        *,
        bursts: BurstProcess | None = None,
        medium: Medium | None = None,
        group: object = None,
    ):
        self.config = config
        self.rng = rng
        self.outages = list(outages)  # (start_s, end_s)
        self._sending: collections.deque[tuple[float, int]] = collections.deque()  # (written at, byte)
        self._in_flight: collections.deque[tuple[float, int]] = collections.deque()
        self._line_free_at = 0.0
        self._per_byte = 1.0 / config.bytes_per_s
        self.bytes_sent = 0
        self.bytes_delivered = 0
        self.bytes_lost = 0
        self.bytes_corrupted = 0
        self.lost_by = {"outage": 0, "noise": 0, "collision": 0}
        self.bytes_in_bursts = 0
        self.tap = None  # called with (data, now_s) for every write: an eavesdropper (attacker.py)
        # What each byte risks: outside bursts (and without them) the configured shares; inside
        # bursts those over the burst share.
        self.bursts = None
        self._burst = None
        p_loss, p_err = config.byte_loss, config.bit_error
        if config.bursts:
            self.bursts = bursts or BurstProcess(config.burst_mean_s, config.burst_share, rng)
            self._burst = self.bursts.view()
            p_loss, p_err = p_loss / config.burst_share, p_err / config.burst_share
        self._p_loss = p_loss
        if p_err and p_loss:  # among the bytes that get through
            p_err = p_err / (1.0 - p_loss) if p_loss < 1.0 else 0.0
        self._p_err = p_err
        self._jitter_s = config.jitter_s
        self._last_arrival = -math.inf
        self._extra_s = 0.0
        self.medium = None
        self._last_end = -math.inf  # when this end's last byte left the air (the medium's)
        if config.half_duplex:
            self.medium = medium or Medium()
            self.medium.attach(self, group)
        # The frames: kinds of those the sender finished writing, in order, and the one on the air.
        self._partial = bytearray()
        self._partial_over = False
        self._kinds: collections.deque[str] = collections.deque()
        self._frame_len = 0  # bytes of the frame now going on the air, so far
        self._frame_damaged = False
        self.frames: dict[str, list[int]] = {}  # kind -> [on the air, damaged]

    def in_outage(self, t_s: float) -> bool:
        return any(a <= t_s < b for a, b in self.outages)

    def write(self, data: bytes, now_s: float) -> None:
        if self.tap is not None:
            self.tap(data, now_s)
        self._sending.extend((now_s, b) for b in data)
        self.bytes_sent += len(data)
        self._follow_frames(data)

    def _follow_frames(self, data: bytes) -> None:
        """Note the kind of each frame the sender finishes (at its 0x00) for the per-kind counts."""
        start = 0
        while True:
            i = data.find(0, start)
            piece = data[start:] if i < 0 else data[start:i]
            if not self._partial_over:
                if len(self._partial) + len(piece) > _MAX_PARTIAL:
                    self._partial_over = True
                    self._partial.clear()
                else:
                    self._partial += piece
            if i < 0:
                return
            if self._partial_over:
                self._kinds.append("malformed")
            elif self._partial:  # an empty frame (two delimiters) is none
                self._kinds.append(frame_kind(bytes(self._partial)))
            self._partial.clear()
            self._partial_over = False
            start = i + 1

    def queued(self) -> int:
        return len(self._sending)

    def advance(self, now_s: float) -> None:
        """Put on the air every byte the line rate allows up to now."""
        if self.medium is not None:
            self.medium.advance(now_s)
        else:
            self._advance_alone(now_s)

    def _advance_alone(self, now_s: float) -> None:
        per_byte = self._per_byte
        sending = self._sending
        while sending:
            written_at, byte = sending[0]
            t = max(self._line_free_at, written_at) + per_byte  # when its stop bit is out
            if t > now_s:
                break
            sending.popleft()
            self._line_free_at = t
            self._air(t, byte, False)

    # The medium's side: when the next byte starts, and taking it.
    def _next_start(self) -> float:
        if not self._sending:
            return math.inf
        return max(self._line_free_at, self._sending[0][0])

    def _take(self, t: float, collided: bool) -> None:
        _, byte = self._sending.popleft()
        self._line_free_at = self._last_end = t
        self._air(t, byte, collided)

    def _air(self, t: float, byte: int, collided: bool) -> None:
        """One byte whose stop bit leaves at t: lost, corrupted or on its way; counted to its frame."""
        if self._frame_len == 0 and self._jitter_s:  # a frame's first byte: its extra delay
            self._extra_s = float(self.rng.exponential(self._jitter_s))
        self._frame_len += 1
        original = byte
        lost = None
        if collided:
            lost = "collision"
        elif self.outages and self.in_outage(t):
            lost = "outage"
        elif self._p_loss or self._p_err:
            in_burst = True
            if self._burst is not None:
                in_burst = self._burst.bad(t)
                self.bytes_in_bursts += in_burst
            if in_burst:
                if self._p_loss and self.rng.random() < self._p_loss:
                    lost = "noise"
                elif self._p_err and self.rng.random() < self._p_err:
                    byte ^= 1 << int(self.rng.integers(8))
                    self.bytes_corrupted += 1
                    self._frame_damaged = True
        if lost is not None:
            self.bytes_lost += 1
            self.lost_by[lost] += 1
            self._frame_damaged = True
        elif self._jitter_s:
            arrival = max(t + self.config.delay_s + self._extra_s, self._last_arrival)  # never overtakes
            self._last_arrival = arrival
            self._in_flight.append((arrival, byte))
        else:
            self._in_flight.append((t + self.config.delay_s, byte))
        if original == 0:  # the frame's delimiter
            if self._frame_len > 1:
                kind = self._kinds.popleft() if self._kinds else "malformed"
                counts = self.frames.get(kind)
                if counts is None:
                    counts = self.frames[kind] = [0, 0]
                counts[0] += 1
                counts[1] += self._frame_damaged
            self._frame_len = 0
            self._frame_damaged = False

    def receive(self, now_s: float, max_bytes: int = 1 << 30) -> bytes:
        """The bytes that have arrived by now (at most max_bytes)."""
        self.advance(now_s)
        out = bytearray()
        while self._in_flight and self._in_flight[0][0] <= now_s and len(out) < max_bytes:
            out.append(self._in_flight.popleft()[1])
        self.bytes_delivered += len(out)
        return bytes(out)

    def byte_counters(self) -> dict:
        """The byte counts (report.json's link.to_rover and link.to_host)."""
        return {
            "bytes_sent": self.bytes_sent,
            "bytes_delivered": self.bytes_delivered,
            "bytes_lost": self.bytes_lost,
            "bytes_corrupted": self.bytes_corrupted,
        }

    def counters(self) -> dict:
        """Bytes (lost by cause), and frames on the air and damaged, in all and by message kind."""
        frames = {kind: {"sent": c[0], "damaged": c[1]} for kind, c in sorted(self.frames.items())}
        return {
            **self.byte_counters(),
            "bytes_lost_by": dict(self.lost_by),
            "bytes_in_bursts": self.bytes_in_bursts,
            "frames_sent": sum(c[0] for c in self.frames.values()),
            "frames_damaged": sum(c[1] for c in self.frames.values()),
            "frames": frames,
        }


def channel_pair(
    config: ChannelConfig, rng: np.random.Generator, outages: list[tuple[float, float]] = ()
) -> tuple[Channel, Channel]:
    """The simulator's radio: (to_rover, to_host), sharing one burst process and, half duplex,
    one medium. Nothing is drawn here."""
    bursts = BurstProcess(config.burst_mean_s, config.burst_share, rng) if config.bursts else None
    medium = Medium() if config.half_duplex else None
    return (
        Channel(config, rng, outages, bursts=bursts, medium=medium),
        Channel(config, rng, outages, bursts=bursts, medium=medium),
    )


class Broadcast:
    """One transmitter heard by several receivers: the host's radio in a fleet. `write` puts the
    same bytes, at the same time, in each receiver's Channel (one transmitter on the medium: they
    do not collide with each other); each receiver loses or keeps them by its own draws."""

    def __init__(self, channels: list[Channel]):
        self.channels = channels

    def write(self, data: bytes, now_s: float) -> None:
        for c in self.channels:
            c.write(data, now_s)

    def queued(self) -> int:
        return max((c.queued() for c in self.channels), default=0)


def fleet_channels(
    config: ChannelConfig, rng: np.random.Generator, rovers: int, outages: list[tuple[float, float]] = ()
) -> tuple[Broadcast, list[Channel], list[Channel]]:
    """A fleet's radio: the host's Broadcast, its Channel to each rover, and each rover's Channel
    to the host, all on one half-duplex medium when the config says half duplex (a rover's bytes
    then collide with the host's and with every other rover's), one burst process for all."""
    if rovers < 1:
        raise ValueError(f"a fleet of {rovers} rovers")
    bursts = BurstProcess(config.burst_mean_s, config.burst_share, rng) if config.bursts else None
    medium = Medium() if config.half_duplex else None
    host = object()  # the host's transmitter: one group on the medium
    to_rovers = [Channel(config, rng, outages, bursts=bursts, medium=medium, group=host) for _ in range(rovers)]
    to_host = [Channel(config, rng, outages, bursts=bursts, medium=medium) for _ in range(rovers)]
    return Broadcast(to_rovers), to_rovers, to_host


def radio_figures(to_rover: Channel, to_host: Channel, t_s: float) -> dict:
    """report.json's "radio": the settings, the bursts as they fell, and each direction's counts."""
    bursts = to_rover.bursts or to_host.bursts
    return {
        "settings": to_rover.config.settings(),
        "bursts": None if bursts is None else bursts.stats(t_s),
        "to_rover": to_rover.counters(),
        "to_host": to_host.counters(),
    }


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
