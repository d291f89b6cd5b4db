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

Nothing here reads a clock of its own: `Soak` is given one (time.monotonic on a real radio; a
simulated one in the tests) and how long one wait for the rover may last.
"""

from __future__ import annotations

import array
import collections
import math
import os
import random
import time
from collections.abc import Callable

from . import messages_gen as mg
from .errors import LinkError
from .framing import CRC_BYTES, HEADER_BYTES, SIGNATURE_BYTES
from .link import host_hello
from .path_upload import CHUNK_SPACING_S, Answer, PathUpload
from .quality import LinkQuality

#: The round-trip probe: a CONFIG naming no parameter, which the rover refuses (NACK
#: unknown_param, the same sequence number) without changing anything.
PROBE_PARAM = 0
assert PROBE_PARAM not in {int(p) for p in mg.PARAMS}, "the probe must name no parameter"
PROBE_HZ = 5.0
PROBE_TIMEOUT_S = 2.0  # a probe unanswered this long is lost
HEARTBEAT_S = 0.2  # as link-check
PATH_WAYPOINTS = 32
PATH_EVERY_S = 5.0  # a path load starts this long after the last one ended
PATH_FIRST_S = 1.0  # ... and the first this long into the soak (after a STATUS)
PATH_RESEND_S = 0.4  # the mission's RESEND_S (rovernav.mission.phases)
PATH_GIVE_UP_S = 30.0  # a load not complete after this long is given up (and counted)
PROGRESS_S = 5.0  # a progress line this often
SILENT_S = 1.0  # no frame from the rover this long: a silence (the mission's SILENT_S)
MIN_SOAK_S, MAX_SOAK_S = 1.0, 86_400.0
#: Missions reach their target at 1 % of bytes lost and 0.1 % corrupted (lossy-radio benchmark) ...
TOLERATED_BYTE_DAMAGE = 0.011
#: ... but not reliably at 5 % lost.
FAILING_BYTE_LOSS = 0.05
#: Fewer frames than this one way, and the share lost is a rough figure: the report says so.
FEW_FRAMES = 200
#: The seed's arena (rovernav.config.ArenaConfig), less a margin: where the soak's waypoints lie [mm].
ARENA_MM = ((150, 2200), (150, 1600))

WAYS = {"host_to_rover": "host -> rover", "rover_to_host": "rover -> host"}


# ------------------------------------------------------------------ frames and byte loss


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


def soak_waypoints(index: int) -> list[tuple[int, int]]:
    """The `index`-th soak path: PATH_WAYPOINTS points inside the arena (non-negative mm), a new
    set each time (never driven: no START is sent)."""
    rng = random.Random(index)
    (x0, x1), (y0, y1) = ARENA_MM
    return [(rng.randrange(x0, x1), rng.randrange(y0, y1)) for _ in range(PATH_WAYPOINTS)]


def _percentile(sorted_values, q: float) -> float | None:
    """Nearest-rank percentile of an ascending sequence (None when empty)."""
    if not sorted_values:
        return None
    return sorted_values[max(0, math.ceil(q / 100.0 * len(sorted_values)) - 1)]


def _median(sorted_values) -> float | None:
    n = len(sorted_values)
    if n == 0:
        return None
    return sorted_values[n // 2] if n % 2 else (sorted_values[n // 2 - 1] + sorted_values[n // 2]) / 2


class Soak:
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

    # ---------------------------------------------------------------- figures

    def _way(self, which: str) -> dict:
        d = self.quality.to_rover if which == "host_to_rover" else self.quality.to_host
        received = which == "rover_to_host"
        lengths = dict(self.rx_lengths if received else self.tx_lengths)
        lost = None if d.rate is None else 1.0 - d.rate
        frames = sum(lengths.values())
        out = {
            "frames_sent": d.sent,
            "frames_arrived": min(d.arrived, d.sent),
            "lost_share": None if lost is None else round(lost, 5),
            "byte_damage_equivalent": _round(byte_damage_for(lost, lengths, received), 5),
            "tolerated_lost_share": _round(frame_loss_at(TOLERATED_BYTE_DAMAGE, lengths, received), 4),
            "failing_lost_share": _round(frame_loss_at(FAILING_BYTE_LOSS, lengths, received), 4),
            "mean_frame_bytes": round(sum(n * c for n, c in lengths.items()) / frames, 1) if frames else None,
        }
        if not received:
            out["rover_received_broken"] = self.quality.rover_broken
        return out

    def verdict(self) -> tuple[str, str]:
        """(kind, one line): 'ok' (within what missions are shown to tolerate), 'beyond' (past it,
        short of where they fail), 'failing' (past that), or 'unknown' (a way not measured)."""
        ways = {w: self._way(w) for w in WAYS}
        unmeasured = [WAYS[w] for w, f in ways.items() if f["lost_share"] is None or f["tolerated_lost_share"] is None]
        if unmeasured:
            why = (
                "the rover sent no two STATUS to count by"
                if "host -> rover" in unmeasured
                else "too few frames came from the rover"
            )
            return "unknown", f"advice: frames lost {' and '.join(unmeasured)} not measured ({why}): soak longer"

        def pct(v: float) -> str:
            return f"{100 * v:.1f} %"

        worst = max(ways, key=lambda w: ways[w]["lost_share"] / max(ways[w]["tolerated_lost_share"], 1e-9))
        f = ways[worst]
        few = [WAYS[w] for w, g in ways.items() if g["frames_sent"] < FEW_FRAMES]
        rough = f" (few frames {' and '.join(few)}: a longer soak measures more closely)" if few else ""
        fix = (
            "move the radio (higher, in sight of the rover, away from the motors and the Uno's wires), "
            "change the channel, check both antennas and that both radios use the same air rate, then soak again"
        )
        failing = [w for w, g in ways.items() if g["lost_share"] > g["failing_lost_share"]]
        if failing:
            what = " and ".join(
                f"{pct(ways[w]['lost_share'])} of frames lost {WAYS[w]}, above the {pct(ways[w]['failing_lost_share'])}"
                for w in failing
            )
            return "failing", (
                f"advice: {what} at which missions fail (5 % of bytes lost, for these frames): {fix}{rough}"
            )
        if f["lost_share"] > f["tolerated_lost_share"]:
            return "beyond", (
                f"advice: {pct(f['lost_share'])} of frames lost {WAYS[worst]}, beyond the "
                f"{pct(f['tolerated_lost_share'])} missions are shown to tolerate (1 % of bytes lost "
                f"and 0.1 % corrupted, for these frames; they fail from "
                f"{pct(f['failing_lost_share'])}): missions may run slow or fail; {fix}{rough}"
            )
        t = {w: pct(g["tolerated_lost_share"]) for w, g in ways.items()}
        return "ok", (
            f"verdict: within what missions are shown to tolerate (up to {t['host_to_rover']} of "
            f"frames lost host -> rover and {t['rover_to_host']} rover -> host: 1 % of bytes lost "
            f"and 0.1 % corrupted, for these frames){rough}"
        )

    def summary(self) -> dict:
        """Every figure, for --json (seconds in seconds, shares in [0, 1], None where not measured)."""
        rt = sorted(self.round_trips)
        loads = sorted(self.load_times)
        kind, line = self.verdict()
        hello = self.link.peer_hello
        return {
            "seconds_asked": self.seconds,
            "seconds_run": round(self.elapsed_s, 3),
            "ended_by": self.ended_by,
            "signed": self.link.signer is not None,
            "rover": {
                "boot_id": self.rover_boot_id,
                "restarts": self.restarts,
                "firmware": None if hello is None else f"{hello.firmware_version >> 8}.{hello.firmware_version & 0xFF}",
            },
            **{w: self._way(w) for w in WAYS},
            "round_trip_s": {
                "probe": f"CONFIG of parameter {PROBE_PARAM} (none) -> NACK unknown_param",
                "sent": self.probes_sent,
                "answered": len(rt),
                "unanswered": self._unanswered(),
                "median": _round(_median(rt), 4),
                "p99": _round(_percentile(rt, 99), 4),
                "worst": _round(rt[-1] if rt else None, 4),
            },
            "path_load_s": {
                "waypoints": PATH_WAYPOINTS,
                "started": self.loads_started,
                "completed": len(loads),
                "given_up": self.loads_given_up,
                "refused": len(self.loads_refused),
                "skipped_mission_running": self.loads_skipped,
                "median": _round(_median(loads), 3),
                "worst": _round(loads[-1] if loads else None, 3),
                "chunks_sent": self.chunks_sent,
                "chunks_sent_again": self.chunks_resent,
            },
            "longest_silence_s": round(self.longest_silence_s, 3),
            "silences_over_1s": self.silences,
            "verdict": kind,
            "advice": line if line.startswith("advice:") else None,
            "verdict_line": line,
        }

    def _unanswered(self) -> int:
        """Probes sent and not answered (those still within PROBE_TIMEOUT_S at the end left out)."""
        return self.probes_sent - len(self.round_trips) - len(self._probes)

    def progress_line(self) -> str:
        rt = sorted(self.round_trips)
        med = _median(rt)
        loads = len(self.load_times)
        return (
            f"soak {self.elapsed_s:.0f}/{self.seconds:g} s: {self.quality.line()} (last 10 s); round trip "
            f"{'-' if med is None else f'{1000 * med:.0f} ms'} median of {len(rt)}; {loads} path"
            f"{'' if loads == 1 else 's'} loaded"
        )

    def report_lines(self) -> list[str]:
        s = self.summary()
        out = []
        ended = "" if s["ended_by"] is None else f", ended early ({s['ended_by']})"
        out.append(
            f"soak: {s['seconds_run']:.1f} of {s['seconds_asked']:g} s{ended}; "
            f"{'signed' if s['signed'] else 'unsigned'} frames"
            + (
                f"; the rover restarted {self.restarts} time{'s' if self.restarts != 1 else ''}"
                if self.restarts
                else ""
            )
        )
        for w, name in WAYS.items():
            f = s[w]
            if f["lost_share"] is None:
                out.append(f"  frames lost {name}: not measured")
                continue
            how = (
                "by the rover's STATUS rx_ok against the frames sent"
                + (
                    f"; it counted {f['rover_received_broken']} arriving broken"
                    if f.get("rover_received_broken")
                    else ""
                )
                if w == "host_to_rover"
                else "by gaps in the rover's sequence numbers"
            )
            out.append(
                f"  frames lost {name}: {100 * f['lost_share']:.2f} % "
                f"({f['frames_sent'] - f['frames_arrived']:,} of {f['frames_sent']:,}, {how}); as if "
                f"{100 * f['byte_damage_equivalent']:.2f} % of bytes were lost (frames of "
                f"{f['mean_frame_bytes']:g} bytes on average)"
            )
        r = s["round_trip_s"]
        if r["answered"]:
            out.append(
                f"  round trip (CONFIG probe -> NACK, {PROBE_HZ:g} a second): median {1000 * r['median']:.0f} ms, "
                f"99th percentile {1000 * r['p99']:.0f} ms, worst {1000 * r['worst']:.0f} ms; "
                f"{r['answered']:,} of {r['sent']:,} answered, {r['unanswered']:,} lost one way or the other"
            )
        else:
            out.append(f"  round trip: none of {r['sent']:,} probes answered")
        p = s["path_load_s"]
        if p["completed"]:
            out.append(
                f"  {PATH_WAYPOINTS}-waypoint path load: median {p['median']:.2f} s, worst {p['worst']:.2f} s "
                f"over {p['completed']} loads; {p['chunks_sent_again']} of {p['chunks_sent']} chunks sent again"
                + (f"; {p['given_up']} given up after {PATH_GIVE_UP_S:g} s" if p["given_up"] else "")
                + (f"; {p['refused']} refused ({self.loads_refused[0]})" if p["refused"] else "")
                + (
                    f"; {p['skipped_mission_running']} not sent while the rover was running a mission"
                    if p["skipped_mission_running"]
                    else ""
                )
            )
        elif p["skipped_mission_running"]:
            out.append("  path load: not measured: the rover is running a mission (it would follow a path sent now)")
        else:
            out.append(
                f"  {PATH_WAYPOINTS}-waypoint path load: none completed ({p['started']} started, "
                f"{p['given_up']} given up after {PATH_GIVE_UP_S:g} s, {p['refused']} refused)"
            )
        out.append(
            f"  longest silence from the rover: {s['longest_silence_s']:.2f} s"
            + (f" ({s['silences_over_1s']} of {SILENT_S:g} s or more)" if s["silences_over_1s"] else "")
        )
        out.append(s["verdict_line"])
        return out


def _round(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


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
