"""The Link: messages over a Transport, with sequence numbers, ACK/NACK requests and the HELLO handshake.

    Link(transport)            wraps any Transport (serial port, pty, pipe to the simulator)
    Link(..., address=k)       talks to the rover at address k of a fleet ([fleet]; 0: a lone rover)
    send(message) -> seq       fire and forget (FIX, HEARTBEAT)
    recv(timeout_s)            next decoded frame, or None after timeout_s seconds
    messages(timeout_s)        frames as they arrive, until timeout_s passes with nothing new
    request(message)           send and wait for the rover's ACK/NACK; resend on silence
    handshake(boot_id)         exchange HELLOs and check both ends share one protocol definition

Frames that arrive while request() or handshake() waits for their answer are kept, in order,
and returned by later recv() calls: nothing the rover says is lost, up to MAX_PENDING_FRAMES
kept unread. Past that (a peer flooding the line while nobody calls recv) the oldest are
dropped and counted in `pending_dropped`, so memory stays bounded. Corrupt or unknown frames
are dropped and counted in `counters` (the decoder's, named as on the rover); frames of another
rover of a fleet (another address) are dropped too, counted in `counters.other_address`.

Every wait respects its timeout, also under a continuous flood of bytes: after a deadline the
Link reads on only what had already arrived, for at most _LATE_POLLS reads and _LATE_POLL_S
seconds. A timeout that is NaN, infinite, negative or longer than MAX_TIMEOUT_S raises
InputError (also a ValueError).

Threads: send() may be called from any thread (e.g. a thread streaming fixes). The receiving
calls (recv, messages, request, handshake) serialise on one lock, so a recv() in another
thread cannot take the ACK that request() is waiting for.
"""

from __future__ import annotations

import collections
import logging
import re
import threading
import time
from collections.abc import Callable, Iterator
from types import TracebackType

from .. import __version__
from ..validate import check_number
from .errors import LinkTimeout, Nacked, SchemaMismatch, SigningMismatch
from .framing import DecoderCounters, Frame, FrameDecoder, Signer, Verifier, check_address, encode_frame
from .messages_gen import SCHEMA_HASH, SIGN_HOST_TO_ROVER, SIGN_ROVER_TO_HOST, Fix, Heartbeat, Hello, Nack, Role
from .requests import RequestTracker
from .schema import Message
from .transport import DEFAULT_BAUD, MAX_TIMEOUT_S, Transport, check_timeout

log = logging.getLogger("rovernav.link")

#: Largest read from the transport at once, in bytes.
READ_CHUNK_BYTES = 4096
#: Reads allowed after a deadline to collect bytes that had already arrived ...
_LATE_POLLS = 256
#: ... and for at most this long [s], so a line that never runs dry cannot hold a wait.
_LATE_POLL_S = 0.05
#: Frames kept for recv() before the oldest are dropped: six seconds of a 57,600-baud line
#: carrying nothing but the shortest frames (9 bytes), about 2 MB of Python objects. A
#: mission calls recv() many times a second, so only a flood with nobody reading gets here.
MAX_PENDING_FRAMES = 4096
#: Most re-sends request() will make.
MAX_RETRIES = 100


def version_word(version: str) -> int:
    """HELLO.firmware_version of a "MAJOR.MINOR[...]" version string: major * 256 + minor."""
    match = re.match(r"(\d+)\.(\d+)", version)
    if not match:
        raise ValueError(f"version {version!r} is not MAJOR.MINOR[.PATCH]")
    major, minor = int(match.group(1)), int(match.group(2))
    if major > 0xFF or minor > 0xFF:
        raise ValueError(f"version {version!r} does not fit major * 256 + minor in 16 bits")
    return major * 256 + minor


def host_hello(boot_id: int) -> Hello:
    """The host's HELLO: role host, our schema hash and version, `boot_id` (new at every host start)."""
    return Hello(
        schema_hash=SCHEMA_HASH,
        boot_id=boot_id & 0xFFFFFFFF,
        firmware_version=version_word(__version__),
        role=Role.HOST,
        max_waypoints=0,
    )


class Link:
    """Framed, sequenced messages over a Transport. See the module docstring for the contract."""

    def __init__(
        self,
        transport: Transport,
        hello_resend_s: float = 0.5,
        key: bytes | None = None,
        clock: Callable[[], float] = time.time,
        address: int = 0,
        polls: bool = False,
    ) -> None:
        """hello_resend_s: how often handshake() repeats its HELLO while waiting [s]
        (an Uno resets when its port is opened and misses what is sent during boot).
        key: the link key ([signing]): every frame but HELLO is then signed, and only the
        rover's signed frames (and its HELLO) are taken; handshake() refuses a rover that says it
        holds no key (a downgrade is not accepted).
        clock: the signing counter's clock, Unix seconds (the wall clock; the simulator's
        simulated one, so that a run does not depend on how fast the machine runs it).
        address: the rover's address in a fleet ([fleet]: 0..MAX_ROVERS - 1, its fleet id - 1; 0 a
        lone rover): every frame sent carries it, and frames of other addresses are dropped (counted
        in counters.other_address). ValueError outside 0..MAX_ROVERS - 1.
        polls: follow each frame but a FIX or a HEARTBEAT with a HEARTBEAT (a rover of a fleet
        speaks only when polled)."""
        #: The rover's address this Link talks to ([fleet]).
        self.address = check_address(address)
        #: Every frame but a FIX or a HEARTBEAT is followed by a HEARTBEAT, the poll a rover of a
        #: fleet waits for before it speaks ([fleet]): a Link on its own to a fleet rover (a
        #: fleet's host schedules its polls itself: fleet/radio.py).
        self.polls = polls
        self.transport = transport
        self.signer = None if key is None else Signer(key, SIGN_HOST_TO_ROVER, clock=clock)
        verifier = None if key is None else Verifier(key, SIGN_ROVER_TO_HOST, require=True)
        self.hello_resend_s = check_number("hello_resend_s", hello_resend_s, 0.0, MAX_TIMEOUT_S, lo_open=True)
        #: The rover's HELLO from the last successful handshake(), else None.
        self.peer_hello: Hello | None = None
        self._decoder = FrameDecoder(verifier, address=self.address)
        self._pending: collections.deque[Frame] = collections.deque()
        self._pending_dropped = 0
        self._next_seq = 0
        self._tx_frames = 0
        self._tx_bytes = 0
        self._rx_bytes = 0
        self._tx_lock = threading.Lock()
        self._rx_lock = threading.RLock()

    # ------------------------------------------------------------ counters

    @property
    def counters(self) -> DecoderCounters:
        """Frames received and dropped, by reason (live object, the decoder's own)."""
        return self._decoder.counters

    @property
    def tx_frames(self) -> int:
        """Frames written to the transport."""
        return self._tx_frames

    @property
    def tx_bytes(self) -> int:
        """Bytes written to the transport, delimiters included."""
        return self._tx_bytes

    @property
    def rx_bytes(self) -> int:
        """Bytes read from the transport, garbage included."""
        return self._rx_bytes

    @property
    def pending_dropped(self) -> int:
        """Valid frames dropped unread because MAX_PENDING_FRAMES were already waiting for recv()."""
        return self._pending_dropped

    # ------------------------------------------------------------ sending

    def send(self, message: Message) -> int:
        """Frame message with the next sequence number (0..255, wrapping) and write it.

        Returns the sequence number used. ValueError (naming the field) if a field is out of
        range, before anything is written or a sequence number is used; LinkClosed or
        LinkTimeout from the transport.
        """
        with self._tx_lock:
            seq = self._next_seq
            frame = encode_frame(
                message, seq, None if isinstance(message, Hello) else self.signer, address=self.address
            )
            self._next_seq = (seq + 1) & 0xFF
            if self.polls and message.ID not in (Fix.ID, Heartbeat.ID):
                # A rover of a fleet answers only when polled ([fleet]): the poll right behind.
                poll = Heartbeat(host_time_ms=0, camera=0, scan_heard=0, path_id=0)
                frame += encode_frame(poll, self._next_seq, self.signer, address=self.address)
                self._next_seq = (self._next_seq + 1) & 0xFF
                self._tx_frames += 1
            self.transport.write(frame)
            self._tx_frames += 1
            self._tx_bytes += len(frame)
        log.debug("tx %s seq=%d %s", message.NAME.upper(), seq, message)
        return seq

    # ------------------------------------------------------------ receiving

    def recv(self, timeout_s: float | None = 0.0) -> Frame | None:
        """The next frame received, oldest first.

        Waits at most timeout_s seconds [s] for one (0: only what has already arrived;
        None: no limit). Returns None if no complete valid frame arrived in time. Raises
        LinkClosed once the transport is closed, or its other end is and all it sent is read.
        """
        with self._rx_lock:
            if self._pending:
                return self._pending.popleft()
            return self._await(lambda frame: True, self._deadline(timeout_s))

    def messages(self, timeout_s: float | None = 0.0) -> Iterator[Frame]:
        """Yield frames as they arrive; stop once timeout_s seconds [s] pass with none.

        The timeout restarts after each frame, so a talkative rover keeps the iterator going.
        With timeout_s=0 it yields what has already arrived and stops.
        """
        while True:
            frame = self.recv(timeout_s)
            if frame is None:
                return
            yield frame

    @property
    def pending(self) -> int:
        """Frames decoded and queued but not yet returned by recv()."""
        return len(self._pending)

    # ------------------------------------------------------------ commands

    def request(self, message: Message, timeout_s: float = 1.0, retries: int = 2) -> Frame:
        """Send message and wait for the rover's ACK (returned) or NACK (raised as Nacked).

        Waits timeout_s seconds [s] per attempt; with no answer, re-sends with a new sequence
        number, up to `retries` more times, then raises LinkTimeout naming the message. A late
        answer to an earlier attempt is accepted. Other frames arriving meanwhile are queued
        for recv().
        """
        check_number("timeout_s (seconds)", timeout_s, 0.0, MAX_TIMEOUT_S, lo_open=True)
        retries = int(check_number("retries", retries, 0, MAX_RETRIES, integer=True))
        tracker = RequestTracker(resend_s=timeout_s, max_tries=retries + 1)
        with self._rx_lock:
            pending = tracker.sent(message, self.send(message), time.monotonic())
            while True:
                reply = self._await(lambda frame: tracker.matches(frame.message), self._deadline(timeout_s))
                if reply is not None:
                    tracker.answer(reply.message)
                    if isinstance(reply.message, Nack):
                        nack = reply.message
                        log.info("%s refused: reason %d detail %d", message.NAME.upper(), nack.reason, nack.detail)
                        raise Nacked(message.NAME, nack.reason, nack.detail)
                    return reply
                if tracker.exhausted(pending):
                    break
                log.warning(
                    "no answer to %s on %s within %.3g s; resending (%d of %d)",
                    message.NAME.upper(),
                    self.transport,
                    timeout_s,
                    pending.tries,
                    retries,
                )
                tracker.resent(pending, self.send(message), time.monotonic())
        raise LinkTimeout(
            f"no ACK or NACK for {message.NAME.upper()} from the rover on {self.transport} "
            f"after {retries + 1} attempts of {timeout_s:g} s"
        )

    def handshake(self, boot_id: int, timeout_s: float = 2.0) -> Hello:
        """Exchange HELLOs with the rover and check it was built from our protocol definition.

        Sends our HELLO (role host, SCHEMA_HASH, our version) every hello_resend_s seconds
        until the rover's HELLO arrives or timeout_s seconds [s] pass. Returns the rover's
        HELLO (also kept as .peer_hello). Raises SchemaMismatch if its schema hash differs,
        LinkTimeout if none came, also while other frames or junk bytes keep arriving. Other
        frames arriving meanwhile are queued for recv() (at most MAX_PENDING_FRAMES, then the
        oldest are dropped and counted in pending_dropped). InputError for a timeout that is
        not a finite number of seconds in (0, MAX_TIMEOUT_S].
        """
        check_number("timeout_s (seconds)", timeout_s, 0.0, MAX_TIMEOUT_S, lo_open=True)
        ours = host_hello(int(check_number("boot_id", boot_id, integer=True)))
        if self.signer is not None:
            ours.signing = 1

        def is_rover_hello(frame: Frame) -> bool:
            return isinstance(frame.message, Hello) and frame.message.role == Role.ROVER

        with self._rx_lock:
            deadline = time.monotonic() + timeout_s
            reply = None
            while reply is None:
                self.send(ours)
                resend_at = min(deadline, time.monotonic() + self.hello_resend_s)
                reply = self._await(is_rover_hello, resend_at)
                if reply is None and time.monotonic() >= deadline:
                    baud = getattr(self.transport, "baud", DEFAULT_BAUD)
                    raise LinkTimeout(
                        f"no HELLO from the rover on {self.transport}: is it powered, "
                        f"flashed, and on this port at {baud} baud?"
                    )
        theirs: Hello = reply.message  # type: ignore[assignment]
        if theirs.schema_hash != SCHEMA_HASH:
            raise SchemaMismatch(SCHEMA_HASH, theirs.schema_hash)
        rover_signs = bool(theirs.signing & 1)
        if self.signer is not None and not rover_signs:
            raise SigningMismatch(
                "the rover says it holds no link key: it would take anyone's commands. "
                "Provision it with this host's key, or remove [link] key_file to run unsigned"
            )
        if self.signer is None and rover_signs:
            raise SigningMismatch(
                "the rover holds a link key and refuses unsigned commands: give this host "
                "the same key ([link] key_file)"
            )
        self._follow_rover_counter(reply)
        self.peer_hello = theirs
        log.info(
            "rover on %s: schema 0x%08X, firmware %d.%d, boot id 0x%08X, holds %d waypoints",
            self.transport,
            theirs.schema_hash,
            theirs.firmware_version >> 8,
            theirs.firmware_version & 0xFF,
            theirs.boot_id,
            theirs.max_waypoints,
        )
        return theirs

    # ------------------------------------------------------------ lifetime

    def close(self) -> None:
        """Close the transport."""
        self.transport.close()

    def __enter__(self) -> Link:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"<Link on {self.transport} tx={self._tx_frames} rx={self.counters.frames_ok} pending={len(self._pending)}>"
        )

    # ------------------------------------------------------------ internals

    @staticmethod
    def _deadline(timeout_s: float | None) -> float | None:
        timeout_s = check_timeout("timeout_s", timeout_s)
        if timeout_s is None:
            return None
        return time.monotonic() + timeout_s

    def _keep(self, frame: Frame) -> None:
        """Queue a frame for recv(), dropping the oldest when MAX_PENDING_FRAMES are waiting."""
        if len(self._pending) >= MAX_PENDING_FRAMES:
            self._pending.popleft()
            if self._pending_dropped == 0:
                log.warning(
                    "%d frames from %s are waiting unread; dropping the oldest from now on",
                    MAX_PENDING_FRAMES,
                    self.transport,
                )
            self._pending_dropped += 1
        self._pending.append(frame)

    def _await(self, wanted: Callable[[Frame], bool], deadline: float | None) -> Frame | None:
        """Read until a frame with wanted(frame) arrives (returned) or the deadline passes (None).

        Every other frame read meanwhile, including those behind the wanted one in the same
        read, is queued for recv() in arrival order. Once the deadline has passed it still
        reads what has already arrived (up to _LATE_POLLS reads and _LATE_POLL_S seconds, so a
        transport that never runs dry cannot hold it): a frame whose bytes are all there is
        not missed.
        """
        late_polls = 0
        while True:
            now = time.monotonic()
            left = None if deadline is None else max(0.0, deadline - now)
            found = None
            frames, got_bytes = self._read_frames(left)
            for frame in frames:
                if found is None and wanted(frame):
                    found = frame
                else:
                    self._keep(frame)
            if found is not None:
                return found
            if left == 0.0:
                late_polls += 1
                if not got_bytes or late_polls > _LATE_POLLS or now - deadline > _LATE_POLL_S:
                    return None

    def _read_frames(self, timeout_s: float | None) -> tuple[list[Frame], bool]:
        """One read from the transport: the frames completed by it, and whether any byte came."""
        data = self.transport.read(READ_CHUNK_BYTES, timeout_s)
        if not data:
            return [], False
        self._rx_bytes += len(data)
        dropped_before = self.counters.dropped
        frames = self._decoder.feed(data)
        dropped = self.counters.dropped - dropped_before
        if dropped:
            log.debug("rx dropped %d bad frame(s) on %s; counters now %s", dropped, self.transport, self.counters)
        for frame in frames:
            log.debug("rx %s seq=%d %s", frame.message.NAME.upper(), frame.seq, frame.message)
            self._follow_rover_counter(frame)
        return frames, True

    def _follow_rover_counter(self, frame: Frame) -> None:
        """A rover's signed HELLO (at its boot, or answering ours) says the least counter it takes
        next: after a reset that is past anything it took before, so a recording cannot be played
        back to it. Our counter jumps past it. Only a HELLO whose tag we checked moves it."""
        m = frame.message
        if (
            self.signer is not None
            and frame.counter is not None
            and isinstance(m, Hello)
            and m.role == Role.ROVER
            and m.signing & 1
        ):
            self.signer.jump_past((m.min_counter_hi << 32 | m.min_counter_lo) - 1)
