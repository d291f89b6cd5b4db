"""Frames on the wire: COBS, a 0x00 delimiter, and a CRC-16/CCITT-FALSE.

    frame   = COBS(body) 0x00
    body    = version:u8 | msg_id:u8 | seq:u8 | payload | crc:u16le
    crc     = CRC-16/CCITT-FALSE(version .. payload)
              (poly 0x1021, init 0xFFFF, no reflection, xorout 0; check("123456789") = 0x29B1)

The decoder takes bytes as they come, allocates nothing per byte that it keeps, resynchronises
at the next 0x00 after garbage, and counts what it drops exactly as the rover's C++ decoder
(firmware/lib/link/frame.h) does, so the two ends' counters mean the same thing:

    overlong    more than MAX_ENCODED_BODY bytes before a delimiter
    malformed   broken COBS, shorter than a header and CRC, wrong version, wrong payload length
    bad_crc     CRC mismatch
    unknown_id  a well-formed frame whose message id we do not know

Checks run in that order; an empty frame (two delimiters in a row) is not counted.

A fleet ([fleet] in protocol/messages.toml): bits ADDRESS_SHIFT.. of the version byte are the
address of the rover a frame is to or from (0..MAX_ROVERS - 1; a lone rover's is 0, so its frames
are what they were before addresses). encode_frame() writes its `address`; a decoder for one
address drops the frames of the others after the version's check, before anything reads their id
or checks their tag, and counts them apart (`other_address`: someone else's frames, not damage,
so not in `dropped`); a decoder for address None takes any (`rovernav provision`, which learns the
rover's address from its HELLO).

Signed frames ([signing] in protocol/messages.toml; the rover checks them the same way,
firmware/lib/link/frame_auth.cpp): the version byte carries SIGN_FLAG, and a counter and a
SipHash-2-4 tag follow the payload. A decoder given a Verifier checks them after the CRC and
counts what it refuses, in this order:

    replayed    the counter is not above the last accepted one (a replay, or reordered)
    bad_tag     the tag is not the key's for this frame and direction (forged, altered, reflected)
    not_signed  an unsigned frame where the Verifier requires signatures (HELLO excepted)
    unverified  a signed frame and no key to check it with (a HELLO is still read, unchecked: it
                tells a host without the key what it lacks)
"""

from __future__ import annotations

import dataclasses
import hmac
import time

from .messages_gen import (
    ADDRESS_MASK,
    ADDRESS_SHIFT,
    MAX_ROVERS,
    MAX_SIGNED_RAW_FRAME,
    MESSAGES,
    PROTOCOL_VERSION,
    SIGN_COUNTER_BYTES,
    SIGN_EPOCH_UNIX_S,
    SIGN_FLAG,
    SIGN_TAG_BYTES,
    SIGN_UNSIGNED_IDS,
    UART_BUFFER_BYTES,
    VERSION_MASK,
)
from .schema import Message
from .siphash import KEY_BYTES, siphash24

HEADER_BYTES = 3
CRC_BYTES = 2
SIGNATURE_BYTES = SIGN_COUNTER_BYTES + SIGN_TAG_BYTES
#: Longest COBS-encoded body (without the delimiter) a valid frame, signed or not, can have.
MAX_ENCODED_BODY = MAX_SIGNED_RAW_FRAME + (MAX_SIGNED_RAW_FRAME + 253) // 254
#: Longest frame on the wire, delimiter included. The rover's buffers are sized for it.
MAX_FRAME = MAX_ENCODED_BODY + 1
assert MAX_FRAME <= UART_BUFFER_BYTES, "a frame must fit the Uno's serial buffer"


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE of data. crc16(b"123456789") == 0x29B1."""
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]
    return crc


def cobs_encode(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing: the result has no 0x00 byte (delimiter not added)."""
    out = bytearray()
    start = 0
    n = len(data)
    while True:
        # a block is up to 254 non-zero bytes, ended by a zero or by the data's end
        end = start
        while end < n and data[end] != 0 and end - start < 254:
            end += 1
        block = data[start:end]
        if len(block) == 254:
            out.append(0xFF)
            out += block
            start = end
            if start == n:  # data ends on a full block: no final code byte
                break
            continue
        out.append(len(block) + 1)
        out += block
        if end >= n:
            break
        start = end + 1  # skip the zero this block stands for
    return bytes(out)


def cobs_decode(data: bytes) -> bytes | None:
    """Inverse of cobs_encode; None if data is not valid COBS (a block runs past the end, or a 0x00)."""
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        code = data[i]
        if code == 0 or i + code > n:
            return None
        block = data[i + 1 : i + code]
        if 0 in block:
            return None
        out += block
        i += code
        if code < 0xFF and i < n:
            out.append(0)
    return bytes(out)


def frame_tag(key: bytes, direction: int, signed_part: bytes) -> bytes:
    """The tag of a signed frame: the first SIGN_TAG_BYTES bytes of SipHash-2-4 under `key` of
    the direction byte and everything from the version byte to the counter."""
    return siphash24(key, bytes((direction,)) + signed_part).to_bytes(8, "little")[:SIGN_TAG_BYTES]


class Signer:
    """Signs the frames one end sends: its key, its direction (SIGN_HOST_TO_ROVER for the host)
    and its counter, the milliseconds since SIGN_EPOCH_UNIX_S or one more than the last, whichever
    is larger (no state to keep across restarts; `jump_past` after a rover says where it stands)."""

    def __init__(self, key: bytes, direction: int, clock=time.time):
        if len(key) != KEY_BYTES:
            raise ValueError(f"a link key is {KEY_BYTES} bytes, got {len(key)}")
        self.key, self.direction, self._clock = bytes(key), direction, clock
        self.last_counter = 0

    def next_counter(self) -> int:
        now_ms = int((self._clock() - SIGN_EPOCH_UNIX_S) * 1000)
        self.last_counter = max(self.last_counter + 1, now_ms)
        if self.last_counter >= 1 << (8 * SIGN_COUNTER_BYTES):
            raise OverflowError("the signing counter has run out of range")
        return self.last_counter

    def jump_past(self, counter: int) -> None:
        """Counters from now on are above `counter` (a rover's minimum after a reset)."""
        self.last_counter = max(self.last_counter, counter)


def check_address(address: int) -> int:
    """`address` if it is a rover's address (0..MAX_ROVERS - 1), else ValueError naming the range."""
    if isinstance(address, bool) or not isinstance(address, int) or not 0 <= address < MAX_ROVERS:
        raise ValueError(f"a rover's address is 0..{MAX_ROVERS - 1} (fleet id - 1; 0 alone), got {address!r}")
    return address


def frame_address(version: int) -> int:
    """The rover's address a frame's version byte carries."""
    return (version & ADDRESS_MASK) >> ADDRESS_SHIFT


def encode_frame(message: Message, seq: int, signer: Signer | None = None, address: int = 0) -> bytes:
    """The bytes to send for message with sequence number seq (0..255), delimiter included, to
    (or from) the rover at `address` ([fleet]; 0: a lone rover); signed (a counter and a tag before
    the CRC) when a Signer is given."""
    if not 0 <= seq <= 0xFF:
        raise ValueError(f"sequence number {seq} is not a byte")
    version = PROTOCOL_VERSION | check_address(address) << ADDRESS_SHIFT
    if signer is None:
        body = bytes((version, message.ID, seq)) + message.pack()
    else:
        body = bytes((version | SIGN_FLAG, message.ID, seq)) + message.pack()
        body += signer.next_counter().to_bytes(SIGN_COUNTER_BYTES, "little")
        body += frame_tag(signer.key, signer.direction, body)
    body += crc16(body).to_bytes(2, "little")
    return cobs_encode(body) + b"\x00"


class Verifier:
    """Checks the signed frames one end receives: the key, the sender's direction byte, and the
    last counter accepted. `require`: refuse unsigned frames (but SIGN_UNSIGNED_IDS)."""

    def __init__(self, key: bytes, direction: int, require: bool = True):
        if len(key) != KEY_BYTES:
            raise ValueError(f"a link key is {KEY_BYTES} bytes, got {len(key)}")
        self.key, self.direction, self.require = bytes(key), direction, require
        self.last_counter = -1


@dataclasses.dataclass
class DecoderCounters:
    """What the decoder kept and what it dropped, by reason (same names as the rover's)."""

    frames_ok: int = 0
    bad_crc: int = 0
    overlong: int = 0
    unknown_id: int = 0
    malformed: int = 0
    bad_tag: int = 0
    replayed: int = 0
    not_signed: int = 0
    unverified: int = 0
    #: Whole frames for another rover's address ([fleet]): not damage, so not in `dropped`.
    other_address: int = 0

    @property
    def dropped(self) -> int:
        return (
            self.bad_crc
            + self.overlong
            + self.unknown_id
            + self.malformed
            + self.bad_tag
            + self.replayed
            + self.not_signed
            + self.unverified
        )


@dataclasses.dataclass(frozen=True)
class Frame:
    """A frame that passed every check, with its decoded message."""

    msg_id: int
    seq: int
    payload: bytes
    message: Message
    counter: int | None = None  # a signed frame's counter (its tag checked), else None
    address: int = 0  # the rover's address in its version byte ([fleet]; 0 alone)


class FrameDecoder:
    """Turns a byte stream into frames; counts and drops everything else.

    feed() may be given any slice of the stream: a byte, a partial frame, several frames. It
    holds at most MAX_ENCODED_BODY bytes between calls, whatever it is fed. `address`: the
    rover's whose frames it takes (0..MAX_ROVERS - 1); None takes every address's.
    """

    def __init__(self, verifier: Verifier | None = None, address: int | None = 0) -> None:
        self.counters = DecoderCounters()
        self.verifier = verifier
        self.address = None if address is None else check_address(address)
        self._buf = bytearray()
        self._overlong = False

    def feed(self, data: bytes) -> list[Frame]:
        frames: list[Frame] = []
        pos = 0
        while pos < len(data):
            end = data.find(0, pos)
            stop = len(data) if end < 0 else end
            if not self._overlong:
                # never holds more than MAX_ENCODED_BODY bytes, however long the run without a delimiter
                if len(self._buf) + (stop - pos) > MAX_ENCODED_BODY:
                    self._overlong = True
                    self._buf.clear()
                else:
                    self._buf += data[pos:stop]
            if end < 0:
                break
            frame = self._finish()
            if frame is not None:
                frames.append(frame)
            pos = end + 1
        return frames

    def _finish(self) -> Frame | None:
        body, overlong = bytes(self._buf), self._overlong
        self._buf.clear()
        self._overlong = False
        if overlong:
            self.counters.overlong += 1
            return None
        if not body:
            return None
        raw = cobs_decode(body)
        if raw is None or len(raw) < HEADER_BYTES + CRC_BYTES:
            self.counters.malformed += 1
            return None
        if crc16(raw[:-2]) != int.from_bytes(raw[-2:], "little"):
            self.counters.bad_crc += 1
            return None
        version, msg_id, seq = raw[0], raw[1], raw[2]
        signed = bool(version & SIGN_FLAG)
        payload = raw[HEADER_BYTES : -CRC_BYTES - (SIGNATURE_BYTES if signed else 0)]
        if (version & VERSION_MASK) != PROTOCOL_VERSION or len(raw) < HEADER_BYTES + CRC_BYTES + (
            SIGNATURE_BYTES if signed else 0
        ):
            self.counters.malformed += 1
            return None
        address = frame_address(version)
        if self.address is not None and address != self.address:
            self.counters.other_address += 1  # another rover's: dropped before its id or its tag is read
            return None
        cls = MESSAGES.get(msg_id)
        if cls is None:
            self.counters.unknown_id += 1
            return None
        if len(payload) != cls.STRUCT.size:
            self.counters.malformed += 1
            return None
        counter = None
        v = self.verifier
        if signed and v is None and msg_id in SIGN_UNSIGNED_IDS:
            pass  # a keyed rover's HELLO, read unchecked: it tells a host without the key what it lacks
        elif signed:
            if v is None:
                self.counters.unverified += 1
                return None
            end = len(raw) - CRC_BYTES
            signed_part, tag = raw[: end - SIGN_TAG_BYTES], raw[end - SIGN_TAG_BYTES : end]
            # The counter first, as the rover checks it: a replay costs no tag.
            counter = int.from_bytes(signed_part[-SIGN_COUNTER_BYTES:], "little")
            if counter <= v.last_counter:
                self.counters.replayed += 1
                return None
            if not hmac.compare_digest(tag, frame_tag(v.key, v.direction, signed_part)):
                self.counters.bad_tag += 1
                return None
            v.last_counter = counter
        elif v is not None and v.require and msg_id not in SIGN_UNSIGNED_IDS:
            self.counters.not_signed += 1
            return None
        self.counters.frames_ok += 1
        return Frame(msg_id, seq, payload, cls.unpack(payload), counter, address)
