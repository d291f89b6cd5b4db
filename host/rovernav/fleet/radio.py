"""One radio for a fleet (issue 30): the host holds the air, and each rover speaks in its slot.

A 433 MHz modem of the seed's kind is half duplex: the host and every rover share 57,600 baud,
5,760 bytes a second both ways. Two transmitters at once destroy each other's bytes, so nobody
speaks out of turn: the host gives the rovers slots in turn. A slot is the host's frames to one
rover (its freshest FIX first, else a HEARTBEAT: something addressed to it), then that rover's
answer: a rover of a fleet sends only in a grant that a frame addressed to it opens, at most
`GRANT_BYTES` whole frames within `GRANT_MS` (protocol/messages.toml [fleet]). The next slot
starts when the last of those bytes can have left the air.

The host's missions never see the shared air: each has a `RoverPort`, a Transport of its own. Its
writes wait in the rover's outbox for the slot; its reads are the frames the radio routed to it
by the address in their version byte (bits 5-6). A frame whose address cannot be read (damaged
before its first bytes) is dropped and counted here; a damaged frame that does reach a port is
refused by that Link's CRC, as on a lone rover's radio.
"""

from __future__ import annotations

import collections
import dataclasses
from collections.abc import Callable

from ..link import messages_gen as mg
from ..link.framing import cobs_decode
from ..link.transport import Transport
from ..vehicle_gen import LINK_BAUD, STEP_PERIOD_MS, UART_BUFFER_BYTES

AIR_BYTES_PER_S = LINK_BAUD / 10.0  # 8N1: ten bits a byte
STEP_S = STEP_PERIOD_MS / 1000.0
#: Slack between one transmitter's last byte and the next one's first [s].
GUARD_S = 0.002
#: A rover whose last grant came back this full has more to say: its slots come four times as often
#: (a sweep's echoes, said three times each, fill its TX queue faster than even slots empty it).
BUSY_SHARE = 0.6
BUSY_WEIGHT = 4.0
#: ... but no rover waits longer than this for its slot (its FIX: a fleet rover's fix_timeout_ms is 1,000, three fixes within it) [s].
MAX_WAIT_S = 0.30
#: At most this many frames in one slot (each is a step more before the rover takes its poll);
#: the rest wait for its next slot.
MAX_SLOT_FRAMES = 3
#: The radio modem's latency, one way (ChannelConfig.delay_s: a 433 MHz modem of the seed's kind) [s].
MODEM_LATENCY_S = 0.015


def turnaround_s(frames: int) -> float:
    """How long after the end of the host's slot a rover may take its poll [s]: it checks one
    signed frame's tag a step, and may leave a step's frames to the next (a sonar result, a job
    put off): a step a frame, and one more."""
    return (frames + 1) * STEP_S


def grant_air_s(frames: int = 1, latency_s: float = MODEM_LATENCY_S) -> float:
    """How long after the end of the host's slot (of `frames` frames) on the air the rover's answer
    can still be on the air [s]: the modem's latency to the rover, its poll taken, its writes within
    GRANT_MS of that step, and what its UART holds then still to go out."""
    last_write_s = _last_write_s()
    tail = min(mg.GRANT_BYTES, UART_BUFFER_BYTES) / AIR_BYTES_PER_S
    return latency_s + turnaround_s(frames) + max(mg.GRANT_BYTES / AIR_BYTES_PER_S, last_write_s + tail) + GUARD_S


def _last_write_s() -> float:
    """How long after the step that opened a grant the rover may still write [s] (0: only in that
    step)."""
    return (mg.GRANT_MS // STEP_PERIOD_MS) * STEP_S


def frame_address(encoded: bytes) -> int | None:
    """The address in a COBS-encoded frame's version byte (the delimiter stripped); None when
    the frame is too short or its first byte is a zero (no version byte can be)."""
    if len(encoded) < 2 or encoded[0] < 2:
        return None
    return (encoded[1] >> mg.ADDRESS_SHIFT) & (mg.MAX_ROVERS - 1)


def _said(frame: bytes) -> bytes | None:
    """A frame's message id and payload (its version, sequence number, signature and CRC left
    out: what a request sent again repeats); None for a frame that does not decode."""
    raw = cobs_decode(frame.rstrip(b"\x00"))
    if raw is None or len(raw) < 5:
        return None
    signed = raw[0] & mg.SIGN_FLAG
    end = len(raw) - 2 - ((mg.SIGN_COUNTER_BYTES + mg.SIGN_TAG_BYTES) if signed else 0)
    return bytes(raw[1:2]) + bytes(raw[3:end])


@dataclasses.dataclass
class PortLoad:
    """What went through one rover's share of the air."""

    slots: int = 0
    tx_bytes: int = 0  # host to this rover
    tx_frames: int = 0
    rx_bytes: int = 0  # this rover to the host (frames routed to it)
    rx_frames: int = 0

    def summary(self, elapsed_s: float) -> dict:
        per_s = 1.0 / elapsed_s if elapsed_s > 0 else 0.0
        return {
            "slots": self.slots,
            "slots_per_s": round(self.slots * per_s, 2),
            "to_rover_bytes_per_s": round(self.tx_bytes * per_s, 1),
            "from_rover_bytes_per_s": round(self.rx_bytes * per_s, 1),
            "to_rover_frames": self.tx_frames,
            "from_rover_frames": self.rx_frames,
        }


class RoverPort(Transport):
    """One rover's side of the fleet's radio, as its Link sees it."""

    def __init__(self, radio: FleetRadio, index: int) -> None:
        super().__init__(f"{radio.transport.name} rover {index + 1}")
        self.radio = radio
        self.index = index

    def _write(self, data: bytes) -> None:
        self.radio._queue(self.index, data)

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        return self.radio._take(self.index, max_bytes)

    def _close(self) -> None:
        pass


class FleetRadio:
    """The shared air: slots in turn, frames routed by address (see the module's doc)."""

    def __init__(self, transport: Transport, rovers: int, latency_s: float = MODEM_LATENCY_S):
        if not 1 <= rovers <= mg.MAX_ROVERS:
            raise ValueError(f"a fleet of 1 to {mg.MAX_ROVERS} rovers, not {rovers}")
        self.transport = transport
        self.rovers = rovers
        self.latency_s = latency_s
        self.ports = [RoverPort(self, k) for k in range(rovers)]
        self._outbox: list[collections.deque[bytes]] = [collections.deque() for _ in range(rovers)]
        self._inbox = [bytearray() for _ in range(rovers)]
        self._partial = bytearray()
        self.load = [PortLoad() for _ in range(rovers)]
        self.unroutable = 0  # frames whose address could not be read, or no rover of ours has
        self.replaced = 0  # frames sent again while the first was still waiting: the first dropped
        self.air_free_s = 0.0  # when the last slot's answer is off the air
        self._last_slot_s = [-1.0 + k * 1e-3 for k in range(rovers)]  # rover 1 first
        self._heard_since_slot = [0] * rovers  # bytes from each rover since its slot began

    # ---------------------------------------------------------------- the missions' side

    def _queue(self, index: int, data: bytes) -> None:
        # A Link writes whole frames; split them anyway, so that a slot sends whole frames.
        start = 0
        for end in range(len(data)):
            if data[end] == 0:
                self._enqueue(index, bytes(data[start : end + 1]))
                start = end + 1
        if start < len(data):
            self._enqueue(index, bytes(data[start:]))

    def _enqueue(self, index: int, frame: bytes) -> None:
        """A frame waits for its rover's slot; one that says what a frame still waiting says (a
        request sent again before its first went out: the same id and payload) takes its place."""
        box = self._outbox[index]
        said = _said(frame)
        if said is not None:
            for i, waiting in enumerate(box):
                if _said(waiting) == said:
                    box[i] = frame
                    self.replaced += 1
                    return
        box.append(frame)

    def _take(self, index: int, max_bytes: int) -> bytes:
        self.pump()
        box = self._inbox[index]
        out = bytes(box[:max_bytes])
        del box[:max_bytes]
        return out

    def waiting(self, index: int) -> int:
        """Frames waiting for rover `index`'s slot."""
        return len(self._outbox[index])

    # ---------------------------------------------------------------- the air

    def pump(self) -> None:
        """Read what the rovers said and route each frame by its address."""
        while True:
            data = self.transport.read(4096, 0)
            if not data:
                return
            self._partial += data
            while True:
                end = self._partial.find(0)
                if end < 0:
                    break
                encoded = bytes(self._partial[:end])
                del self._partial[: end + 1]
                if not encoded:
                    continue
                address = frame_address(encoded)
                if address is None or address >= self.rovers:
                    self.unroutable += 1
                    continue
                self._inbox[address] += encoded + b"\x00"
                self._heard_since_slot[address] += len(encoded) + 1
                self.load[address].rx_bytes += len(encoded) + 1
                self.load[address].rx_frames += 1

    def next_rover(self, now_s: float) -> int:
        """Whose slot is next: the rover that has waited longest, a rover whose last grant came
        back full (BUSY_SHARE) counting its wait twice, unless some rover has waited MAX_WAIT_S."""
        self.pump()
        waits = [now_s - t for t in self._last_slot_s]
        longest = max(range(self.rovers), key=lambda k: waits[k])
        if waits[longest] >= MAX_WAIT_S:
            return longest
        busy = [h >= BUSY_SHARE * mg.GRANT_BYTES for h in self._heard_since_slot]
        return max(range(self.rovers), key=lambda k: waits[k] * (BUSY_WEIGHT if busy[k] else 1.0))

    def slot(self, now_s: float, fill: Callable[[int, float], None]) -> int | None:
        """If the air is free, the next rover's slot (`next_rover`): `fill(index, now_s)` lets its
        mission write what belongs in the slot (its freshest FIX, or a poll), then everything
        waiting for that rover goes out. Returns the rover's index (None: the air is still taken)."""
        if now_s + 1e-9 < self.air_free_s:
            return None
        for _ in range(self.rovers):  # a rover with nothing (its mission over) passes its turn
            k = self.next_rover(now_s)
            fill(k, now_s)
            box = self._outbox[k]
            if box:
                break
            self._last_slot_s[k] = now_s
        else:
            return None
        # The poll (the last frame written) and at most MAX_SLOT_FRAMES - 1 before it; the rest
        # wait for the next slot, in their order.
        poll = box.pop()
        batch = [box.popleft() for _ in range(min(len(box), MAX_SLOT_FRAMES - 1))]
        data = b"".join(batch) + poll
        self.transport.write(data)
        self._last_slot_s[k] = now_s
        self._heard_since_slot[k] = 0
        load = self.load[k]
        load.slots += 1
        load.tx_bytes += len(data)
        load.tx_frames += data.count(0)
        frames = data.count(0)
        self.air_free_s = now_s + len(data) / AIR_BYTES_PER_S + grant_air_s(frames, self.latency_s)
        return k
