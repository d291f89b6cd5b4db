"""A second transmitter on the rover's frequency (`rovernav sim --attacker`): it records what the
host sends and, every period, injects one frame of its own into the radio model, cycling through

    forged     a STOP signed with a key of its own, its counter far ahead
    replayed   a frame the host sent a while ago, unchanged
    altered    a recorded frame with one payload bit flipped, its counter moved ahead and its
               CRC made good (only the tag can tell)
    unsigned   a STOP with no signature

A rover with the host's key refuses all four (bad_tag, replayed, bad_tag, not_signed) and the
mission goes on. On an unsigned link (`--unsigned`) the rover refuses only the signed forgery
(it has no key: unverified) and obeys the rest: replays, altered frames and STOPs.
"""

from __future__ import annotations

import collections

import numpy as np

from ..link.framing import Signer, cobs_decode, cobs_encode, crc16, encode_frame
from ..link.messages_gen import SIGN_COUNTER_BYTES, SIGN_HOST_TO_ROVER, SIGN_TAG_BYTES, Stop, StopReason
from .channel import Channel

KINDS = ("forged", "replayed", "altered", "unsigned")
EXPECTED_REFUSAL = {"forged": "bad_tag", "replayed": "replayed", "altered": "bad_tag", "unsigned": "not_signed"}


class Attacker:
    def __init__(self, channel: Channel, seed: int, start_s: float = 3.0, period_s: float = 0.5):
        self.channel = channel
        self.rng = np.random.default_rng(seed)
        self.start_s, self.period_s = start_s, period_s
        self._next_s = start_s
        self._heard: collections.deque[tuple[float, bytes]] = collections.deque(maxlen=256)  # (time, raw body)
        self._own = Signer(bytes(self.rng.integers(0, 256, 16, dtype=np.uint8)), SIGN_HOST_TO_ROVER)
        self.injected = {kind: 0 for kind in KINDS}
        self._i = 0
        self._sending = False  # its own frames go through the same channel: not recorded

    def observe(self, data: bytes, now_s: float) -> None:
        """What the host put on the air (whole frames)."""
        if self._sending:
            return
        for encoded in data.split(b"\x00"):
            raw = cobs_decode(encoded) if encoded else None
            if raw and len(raw) > 5:
                self._heard.append((now_s, raw))

    def tick(self, now_s: float) -> None:
        if now_s < self._next_s:
            return
        self._next_s = now_s + self.period_s
        kind = KINDS[self._i % len(KINDS)]
        frame = self._make(kind, now_s)
        if frame is None:
            return
        self._i += 1
        self.injected[kind] += 1
        self._sending = True
        try:
            self.channel.write(frame, now_s)
        finally:
            self._sending = False

    def _old_frame(self, now_s: float) -> bytes | None:
        old = [raw for t, raw in self._heard if t < now_s - 1.0]
        return old[int(self.rng.integers(len(old)))] if old else None

    def _make(self, kind: str, now_s: float) -> bytes | None:
        seq = int(self.rng.integers(256))
        if kind == "forged":
            self._own.jump_past(1 << 46)  # far past anything the host has sent
            return encode_frame(Stop(reason=StopReason.OPERATOR), seq, self._own)
        if kind == "unsigned":
            return encode_frame(Stop(reason=StopReason.OPERATOR), seq)
        raw = self._old_frame(now_s)
        if raw is None:
            return None
        body = bytearray(raw[:-2])
        if kind == "altered":
            signed = bool(body[0] & 0x80)
            end = len(body) - (SIGN_TAG_BYTES if signed else 0)
            payload_len = end - (SIGN_COUNTER_BYTES if signed else 0) - 3
            if payload_len > 0:
                body[3 + int(self.rng.integers(payload_len))] ^= 1 << int(self.rng.integers(8))
            if signed:
                body[end - SIGN_COUNTER_BYTES : end] = ((1 << 46) + self._i).to_bytes(SIGN_COUNTER_BYTES, "little")
        body += crc16(bytes(body)).to_bytes(2, "little")
        return cobs_encode(bytes(body)) + b"\x00"
