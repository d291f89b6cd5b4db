"""Frames lost from bytes lost, for `rovernav link-check --soak` (link/soak.py): a frame's length on
the wire, the share of frames a byte loss loses, and the byte loss that would lose a share.

What missions tolerate, in frames: the lossy-radio benchmark (benchmarks/lossy_radio.py) shows
missions reach their target at 1 % of bytes lost with 0.1 % corrupted (and at 2 % lost in
bursts), but not reliably at 5 % lost. A lost or corrupted byte breaks the frame it is in, and the
frame after it when it is the 0x00 between them, so a frame of L bytes on the wire (its 0x00
included) arrives whole at byte damage p with probability (1 - p) ** (L + 1). The share of
frames lost at p is then, over the frames this soak sent that way (each of its length):

    host to rover   1 - sum(n_L * (1-p)**(L+1)) / sum(n_L)          n_L: frames of L bytes sent
    rover to host   1 - sum(m_L) / sum(m_L / (1-p)**(L+1))          m_L: frames of L bytes received
                                                                    (the lost ones are unseen)

with p = TOLERATED_BYTE_DAMAGE (1.1 %) for what missions tolerate and FAILING_BYTE_LOSS (5 %) for
where they fail. So the thresholds follow the frames measured (signed frames are 12 bytes longer:
the same byte loss loses more of them; the benchmark's missions ran signed). For the frames a mission sends most, `typical_thresholds()`: a HEARTBEAT (12
bytes) 13 % / 49 %, a FIX (18) 19 % / 62 %, a PATH chunk (44) 39 % / 90 %, a STATUS (52) 44 % /
93 %. Losses in bursts break fewer frames for the same bytes lost (the lost bytes fall together,
many in frames already broken): 2 % of bytes lost in bursts, which missions tolerate (10 % of the
time, a fifth of the bytes lost in it), loses about 10 % of frames of any length, below the 1 %
line for frames of 12 bytes and more (a HEARTBEAT's 13 %). The report also gives, each way, the
byte damage under which independent loss would lose the frames measured.
"""

from __future__ import annotations

from . import messages_gen as mg
from .framing import CRC_BYTES, HEADER_BYTES, SIGNATURE_BYTES

#: Missions reach their target at 1 % of bytes lost and 0.1 % corrupted (lossy-radio benchmark) ...
TOLERATED_BYTE_DAMAGE = 0.011
#: ... but not reliably at 5 % lost.
FAILING_BYTE_LOSS = 0.05


def wire_bytes(payload_bytes: int, signed: bool) -> int:
    """Bytes a frame with this payload takes on the wire: header, payload, signature, CRC, COBS's
    overhead and the 0x00."""
    raw = HEADER_BYTES + payload_bytes + (SIGNATURE_BYTES if signed else 0) + CRC_BYTES
    return raw + 1 + raw // 254 + 1


def frame_loss_at(byte_damage: float, lengths: dict[int, int], received: bool) -> float | None:
    """Share of frames lost at `byte_damage` (independent per byte) for frames of these lengths
    ({bytes on the wire: frames}); `received`: the counts are of frames that arrived (the lost ones
    unseen), else of frames sent. None without frames. See the module docstring."""
    if not lengths or sum(lengths.values()) <= 0:
        return None
    keep = {n: (1.0 - byte_damage) ** (n + 1) for n in lengths}
    total = sum(lengths.values())
    if received:
        return 1.0 - total / sum(count / keep[n] for n, count in lengths.items())
    return 1.0 - sum(count * keep[n] for n, count in lengths.items()) / total


def byte_damage_for(frame_loss: float | None, lengths: dict[int, int], received: bool) -> float | None:
    """The byte damage (independent per byte) that would lose `frame_loss` of these frames."""
    if frame_loss is None or not lengths:
        return None
    if frame_loss <= 0.0:
        return 0.0
    lo, hi = 0.0, 0.5
    if (frame_loss_at(hi, lengths, received) or 0.0) < frame_loss:
        return hi
    for _ in range(60):
        mid = (lo + hi) / 2
        if frame_loss_at(mid, lengths, received) < frame_loss:  # type: ignore[operator]
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def typical_thresholds(signed: bool = False) -> dict[str, tuple[int, float, float]]:
    """{message: (bytes on the wire, frames lost at TOLERATED_BYTE_DAMAGE, at FAILING_BYTE_LOSS)}
    for the frames a mission sends most."""
    out = {}
    for cls in (mg.Heartbeat, mg.Fix, mg.Path, mg.Status):
        n = wire_bytes(cls.STRUCT.size, signed)
        out[cls.NAME.upper()] = (
            n,
            frame_loss_at(TOLERATED_BYTE_DAMAGE, {n: 1}, False),
            frame_loss_at(FAILING_BYTE_LOSS, {n: 1}, False),
        )
    return out
