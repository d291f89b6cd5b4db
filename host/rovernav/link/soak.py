"""`rovernav link-check --soak SECONDS`: how well a radio carries the rover's link, measured.

For SECONDS after the HELLO the host keeps up the traffic of an idle session and measures:

  * frames lost each way (rovernav.link.quality.LinkQuality, as a mission measures them). Host to
    rover: the rover's STATUS counts the valid frames it received (rx_ok, 16 bits, wrapping) and
    the broken ones; the host knows what it sent between two STATUS. Rover to host: gaps in the
    sequence numbers of the rover's frames that arrived (0..255, wrapping).
  * the round trip: PROBE_HZ times a second a CONFIG of parameter PROBE_PARAM, which names no
    parameter: the rover answers NACK unknown_param under the same sequence number and changes
    nothing. Median and 99th percentile of the answered ones; a probe unanswered after
    PROBE_TIMEOUT_S is lost (its frame one way or its answer the other).
  * how long a PATH_WAYPOINTS-waypoint path takes to load: PATH_EVERY_S after the last load
    ended, a new path (a new id, waypoints inside the seed's 2.36 x 1.75 m arena) goes up as the
    mission sends one (PathUpload: chunk by chunk, selective retransmission, a chunk unanswered
    PATH_RESEND_S goes again), from its first chunk until the rover holds it whole (every chunk
    ACKed, or its PATH_ACCEPTED event). No START is sent: the rover holds the path and does not
    move. While the rover's STATUS says a mission is running no path is sent (a running rover
    follows a new path at once).
  * HEARTBEATs every HEARTBEAT_S (camera: no frames), as link-check sends them.

What missions tolerate, in frames, and the byte loss that would explain the frames lost: soak_loss.py.
What the soak sends and how often: soak_plan.py. Its figures and report: soak_report.py.

Nothing here reads a clock of its own: `Soak` is given one (time.monotonic on a real radio; a
simulated one in the tests) and how long one wait for the rover may last.
"""

from __future__ import annotations

import array
import collections
import os
import time
from collections.abc import Callable

from . import messages_gen as mg
from .errors import LinkError
from .link import host_hello
from .path_upload import CHUNK_SPACING_S, Answer, PathUpload
from .quality import LinkQuality
from .soak_loss import (
    FAILING_BYTE_LOSS,
    TOLERATED_BYTE_DAMAGE,
    byte_damage_for,
    frame_loss_at,
    typical_thresholds,
    wire_bytes,
)
from .soak_plan import (
    ARENA_MM,
    FEW_FRAMES,
    HEARTBEAT_S,
    MAX_SOAK_S,
    MIN_SOAK_S,
    PATH_EVERY_S,
    PATH_FIRST_S,
    PATH_GIVE_UP_S,
    PATH_RESEND_S,
    PATH_WAYPOINTS,
    PROBE_HZ,
    PROBE_PARAM,
    PROBE_TIMEOUT_S,
    PROGRESS_S,
    SILENT_S,
    WAYS,
    soak_waypoints,
)
from .soak_report import SoakFigures

__all__ = [
    "ARENA_MM",
    "FAILING_BYTE_LOSS",
    "FEW_FRAMES",
    "HEARTBEAT_S",
    "MAX_SOAK_S",
    "MIN_SOAK_S",
    "PATH_EVERY_S",
    "PATH_FIRST_S",
    "PATH_GIVE_UP_S",
    "PATH_RESEND_S",
    "PATH_WAYPOINTS",
    "PROBE_HZ",
    "PROBE_PARAM",
    "PROBE_TIMEOUT_S",
    "PROGRESS_S",
    "SILENT_S",
    "TOLERATED_BYTE_DAMAGE",
    "WAYS",
    "Soak",
    "SoakFigures",
    "byte_damage_for",
    "frame_loss_at",
    "help_text",
    "soak_rover",
    "soak_waypoints",
    "typical_thresholds",
    "wire_bytes",
    "wrap",
]


# ------------------------------------------------------------------ --help


def wrap(text: str, indent: str = "", width: int = 100) -> str:
    """`text` wrapped for --help (the parser keeps the line breaks given)."""
    import textwrap

    return textwrap.fill(
        text, width=width, initial_indent=indent, subsequent_indent=" " * len(indent), break_on_hyphens=False
    )


def help_text() -> str:
    """What --soak measures and how, for `rovernav link-check --help`."""
    typical = "; ".join(
        f"{name} ({n} B) {100 * ok:.0f} % / {100 * bad:.0f} %" for name, (n, ok, bad) in typical_thresholds().items()
    )
    items = [
        "frames lost host -> rover (the rover's STATUS counts the valid frames it received, rx_ok, and "
        "the broken ones: against the frames the host sent between two STATUS) and rover -> host (gaps in the "
        "sequence numbers of the rover's frames), as a mission measures them;",
        f"the round trip, median and 99th percentile, {PROBE_HZ:g} probes a second: a CONFIG of parameter "
        f"{PROBE_PARAM}, which names no parameter, so the rover answers NACK unknown_param under the same "
        "sequence number and changes nothing;",
        f"how long a {PATH_WAYPOINTS}-waypoint path takes to load, median and worst: one every "
        f"{PATH_EVERY_S:g} s, sent as a mission sends it (chunk by chunk, lost chunks sent again), each under a "
        "new path id, its waypoints inside the arena. No START is sent: the rover holds the path and does not "
        "move, so a soak is safe on the bench; no path is sent while its STATUS says it runs a mission;",
        "one line of advice when frames are lost beyond what missions are shown to tolerate. The lossy-radio "
        "benchmark shows missions reach their target at 1 % of bytes lost (with 0.1 % corrupted; and at 2 % "
        "lost in bursts), not reliably at 5 %. A frame of L bytes on the wire arrives whole at byte damage p "
        "with probability (1-p)^(L+1) (its bytes, and the 0x00 ending the frame before it), so the thresholds "
        "are the shares that 1.1 % and 5 % of bytes would lose of the frames the soak sent (and received) each "
        f"way; e.g. {typical} (lost at 1.1 % / at 5 %; signed frames are 12 B longer). The report also gives "
        "the byte loss that would explain the frames lost.",
    ]
    return "\n".join(
        [wrap("--soak SECONDS measures the radio instead, for that long, and reports:")]
        + [wrap(item, "  - ") for item in items]
        + [
            wrap(
                f"Also heartbeats every {HEARTBEAT_S:g} s. A progress line goes to stderr every "
                f"{PROGRESS_S:g} s; Ctrl-C ends the soak early and still prints the report (exit 130); "
                "--json FILE writes the figures. Signed with --key-file, as the rest of link-check."
            )
        ]
    )


# ------------------------------------------------------------------ the soak


class Soak(SoakFigures):
    """Frames with the rover for a while, and what they show. `link` has made its handshake."""

    def __init__(
        self,
        link,
        clock: Callable[[], float] = time.monotonic,
        poll_s: float = 0.02,
        host_boot_id: int | None = None,
        probe_hz: float = PROBE_HZ,
        path_every_s: float = PATH_EVERY_S,
        progress: Callable[[str], None] | None = None,
        progress_s: float = PROGRESS_S,
    ) -> None:
        """clock: seconds, for every figure; poll_s: the longest wait for the rover in one go (0:
        only poll, for a simulated rover that moves on as it is read)."""
        self.link, self.clock, self.poll_s = link, clock, poll_s
        self._chunk_at = -1e9  # when the last PATH chunk went out
        self.probe_every_s = 1.0 / probe_hz
        self.path_every_s = path_every_s
        self.progress, self.progress_s = progress, progress_s
        self.host_boot_id = int.from_bytes(os.urandom(4), "little") if host_boot_id is None else host_boot_id
        self.quality = LinkQuality()
        self.rover_boot_id = link.peer_hello.boot_id if link.peer_hello is not None else None
        self.restarts = 0
        self.tx_lengths: collections.Counter[int] = collections.Counter()
        self.rx_lengths: collections.Counter[int] = collections.Counter()
        # round trips
        self._probes: dict[int, float] = {}  # seq -> when sent
        self.probes_sent = 0
        self.round_trips = array.array("d")
        # path loads
        self._id_hi = os.urandom(1)[0]
        self._upload: PathUpload | None = None
        self._upload_started = 0.0
        self.loads_started = 0
        self.load_times = array.array("d")
        self.loads_given_up = 0
        self.loads_refused: list[str] = []
        self.loads_skipped = 0  # the rover was running a mission
        self.chunks_sent = 0
        self.chunks_resent = 0
        # silences
        self._last_rx: float | None = None
        self.longest_silence_s = 0.0
        self.silences = 0
        self.last_status: mg.Status | None = None
        self.elapsed_s = 0.0
        self.seconds = 0.0
        self.ended_by: str | None = None  # None: ran its time; else why it ended early

    # ---------------------------------------------------------------- sending

    def _send(self, message) -> int:
        before = self.link.tx_bytes
        seq = self.link.send(message)
        self.tx_lengths[self.link.tx_bytes - before] += 1
        return seq

    def _path_id(self, n: int) -> int:
        # The low byte in 0x80..0xFF: a mission numbers its paths (its boot id's low byte) << 8
        # plus 1, 2, ..., so it comes to these only after its 127th path in one run (a rover that
        # holds a path takes another of that id and length as a repeat of it).
        return ((self._id_hi + n // 128) & 0xFF) << 8 | 0x80 | (n % 128)

    def _start_load(self, now: float) -> None:
        n = self.loads_started
        self.loads_started += 1
        self._upload = PathUpload(self._path_id(n), soak_waypoints(self._path_id(n)), PATH_RESEND_S)
        self._upload_started = now

    def _end_load(self, now: float, completed: bool) -> None:
        up = self._upload
        assert up is not None
        if completed:
            self.load_times.append(now - self._upload_started)
        self.chunks_sent += up.frames_sent
        self.chunks_resent += up.frames_resent
        self._upload = None
        self._next_path = now + self.path_every_s

    # ---------------------------------------------------------------- receiving

    def _take(self, frame, now: float) -> None:
        m = frame.message
        if isinstance(m, mg.Hello) and m.role == mg.Role.ROVER and m.boot_id != self.rover_boot_id:
            # The rover restarted: its counters and sequence numbers start again; tell it who we are.
            self.quality.restart()
            self.restarts += 1
            self.rover_boot_id = m.boot_id
            ours = host_hello(self.host_boot_id)
            if self.link.signer is not None:
                ours.signing = 1
            self._send(ours)
        self.quality.on_frame(frame.seq, now)
        self.rx_lengths[wire_bytes(len(frame.payload), frame.counter is not None)] += 1
        if self._last_rx is not None:
            gap = now - self._last_rx
            self.longest_silence_s = max(self.longest_silence_s, gap)
            self.silences += gap >= SILENT_S
        self._last_rx = now
        if isinstance(m, mg.Status):
            self.quality.on_status(m, self.link.tx_frames, now)
            self.last_status = m
        elif isinstance(m, (mg.Ack, mg.Nack)):
            if m.msg_id == mg.Config.ID and m.seq in self._probes:
                self.round_trips.append(now - self._probes.pop(m.seq))
            elif self._upload is not None:
                answer = self._upload.answer(m)
                if answer is Answer.REFUSED:
                    self.loads_refused.append(_nack_text(self._upload.refusal))
                    self._end_load(now, completed=False)
        elif isinstance(m, mg.Event) and m.kind == mg.EventKind.PATH_ACCEPTED:
            if self._upload is not None and m.arg == self._upload.path_id:
                self._upload.mark_complete()
        if self._upload is not None and self._upload.complete:
            self._end_load(now, completed=True)

    # ---------------------------------------------------------------- the loop

    def run(self, seconds: float) -> Soak:
        """Exchange frames for `seconds` (Ctrl-C or a link that fails ends it early: `ended_by`)."""
        clock = self.clock
        self.seconds = seconds
        start = clock()
        end = start + seconds
        next_heartbeat = next_probe = start
        self._next_path = start + PATH_FIRST_S
        next_progress = start + self.progress_s
        try:
            while (now := clock()) < end:
                if now >= next_heartbeat:
                    self._send(mg.Heartbeat(host_time_ms=int(now * 1000) & 0xFFFFFFFF, camera=mg.CameraState.NO_FRAMES))
                    next_heartbeat = max(next_heartbeat + HEARTBEAT_S, now)
                if now >= next_probe:
                    self._probes[self._send(mg.Config(param=PROBE_PARAM, value=0))] = now
                    self.probes_sent += 1
                    next_probe = max(next_probe + self.probe_every_s, now)
                for seq in [s for s, t in self._probes.items() if now - t > PROBE_TIMEOUT_S]:
                    del self._probes[seq]
                self._paths(now)
                if self.progress is not None and now >= next_progress:
                    self.elapsed_s = now - start
                    self.progress(self.progress_line())
                    next_progress += self.progress_s
                wait = min(next_heartbeat, next_probe, end) - clock()
                frame = self.link.recv(max(0.0, min(self.poll_s, wait)))
                if frame is not None:
                    self._take(frame, clock())
        except KeyboardInterrupt:
            self.ended_by = "Ctrl-C"
        except LinkError as exc:
            self.ended_by = str(exc)
        self.elapsed_s = min(clock(), end) - start
        return self

    def _paths(self, now: float) -> None:
        if self._upload is None:
            if now < self._next_path or self.last_status is None:
                return
            if self.last_status.flags & mg.StatusFlag.MISSION_ACTIVE:
                self.loads_skipped += 1  # a running rover would follow it at once
                self._next_path = now + self.path_every_s
                return
            self._start_load(now)
        elif now - self._upload_started > PATH_GIVE_UP_S:
            self.loads_given_up += 1
            self._end_load(now, completed=False)
            return
        up = self._upload
        assert up is not None
        if now - self._chunk_at >= CHUNK_SPACING_S:  # one at a time, as a mission sends them
            for message in up.due(now)[:1]:
                self._chunk_at = now
                up.sent(message, self._send(message), now)


def _nack_text(nack: mg.Nack | None) -> str:
    if nack is None:
        return "refused"
    reason = mg.NackReason(nack.reason).name.lower() if nack.reason in mg.NackReason._value2member_map_ else nack.reason
    return f"NACK {reason} detail {nack.detail}"


def soak_rover(
    link,
    seconds: float,
    hello_timeout_s: float,
    json_path=None,
    *,
    clock: Callable[[], float] = time.monotonic,
    poll_s: float = 0.02,
    progress_s: float = PROGRESS_S,
) -> int:
    """`rovernav link-check --soak`: HELLO, the soak with a progress line on stderr every
    `progress_s`, the report on stdout, the figures to `json_path`. Returns the exit status: 0, or
    130 after Ctrl-C (the report still printed and written); a link that failed mid-soak (a port
    unplugged) prints the report, then raises its error (exit 2)."""
    import sys

    from ..files import write_json_atomic
    from ..validate import check_number
    from .check import greet

    seconds = check_number("--soak (seconds)", seconds, MIN_SOAK_S, MAX_SOAK_S)
    boot_id = int.from_bytes(os.urandom(4), "little")
    greet(link, hello_timeout_s, boot_id=boot_id)
    print(
        f"soaking for {seconds:g} s: heartbeats, {PROBE_HZ:g} round-trip probes a second, a "
        f"{PATH_WAYPOINTS}-waypoint path loaded every {PATH_EVERY_S:g} s (no START: the rover does not move); "
        f"Ctrl-C ends it early",
        flush=True,
    )

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    soak = Soak(link, clock=clock, poll_s=poll_s, host_boot_id=boot_id, progress=progress, progress_s=progress_s)
    soak.run(seconds)
    for line in soak.report_lines():
        print(line)
    if json_path is not None:
        write_json_atomic(json_path, soak.summary())
        print(f"wrote the figures to {json_path}")
    if soak.ended_by == "Ctrl-C":
        return 130
    if soak.ended_by is not None:
        raise LinkError(f"the soak ended after {soak.elapsed_s:.1f} s: {soak.ended_by}")
    return 0
