"""Each exchange between host and rover under a radio that loses, or repeats, chosen frames.

The host is the real Mission (or the PathUpload it uses); the rover is the firmware core through
its C ABI. Between them a pipe drops or duplicates the frames a test names (by kind, and which
occurrence), so every case is exact and repeatable: a lost HELLO, a lost chunk, a lost ACK, a
duplicated frame, a lost START, a lost STOP. A whole mission on a randomly lossy radio is in
test_sim_faults.py (`test_a_mission_at_one_percent_byte_loss_reaches_its_target`).
"""

from __future__ import annotations

from tests.core_transport import CoreRover

from rovernav.link import framing
from rovernav.link import messages_gen as mg
from rovernav.link.link import Link
from rovernav.link.path_upload import Answer, PathUpload, path_chunks
from rovernav.link.transport import PipeTransport, Transport
from rovernav.mission import Detection, Mission, Phase
from rovernav.planning import OccupancyGrid, PlannerConfig


def _frames(data: bytes) -> list[tuple[bytes, object]]:
    """Split bytes into whole wire frames (each with its 0x00), with the message each carries."""
    out, start = [], 0
    for i, b in enumerate(data):
        if b == 0:
            raw = data[start : i + 1]
            start = i + 1
            decoded = framing.FrameDecoder().feed(raw)
            out.append((raw, decoded[0] if decoded else None))
    return out


class Rule:
    """Drop (or duplicate) the `nth` frames (counting from 1) that `match` picks."""

    def __init__(self, match, nth=(1,), action="drop"):
        self.match, self.nth, self.action, self.seen, self.applied = match, set(nth), action, 0, 0

    def apply(self, frame) -> int:
        """How many copies of the frame go on: 0, 1 or 2."""
        if frame is None or not self.match(frame):
            return 1
        self.seen += 1
        if self.seen not in self.nth:
            return 1
        self.applied += 1
        return 0 if self.action == "drop" else 2


class LossyEnd(Transport):
    """The host's end of a pipe that drops or duplicates chosen frames both ways."""

    def __init__(self, inner: Transport, to_rover=(), to_host=()):
        super().__init__("lossy pipe")
        self.inner, self.to_rover, self.to_host = inner, list(to_rover), list(to_host)
        self._partial = b""

    @staticmethod
    def _filter(data: bytes, rules) -> bytes:
        out = b""
        for raw, frame in _frames(data):
            copies = 1
            for rule in rules:
                copies = rule.apply(frame)
                if copies != 1:
                    break
            out += raw * copies
        return out

    def _write(self, data: bytes) -> None:
        self.inner.write(self._filter(data, self.to_rover))

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        data = self._partial + self.inner.read(max_bytes, 0)
        cut = data.rfind(b"\x00") + 1
        self._partial = data[cut:]
        return self._filter(data[:cut], self.to_host)

    def _close(self) -> None:
        pass


def is_(cls, **fields):
    return lambda f: isinstance(f.message, cls) and all(getattr(f.message, k) == v for k, v in fields.items())


def answers(cls):
    """An ACK or NACK of a `cls` message."""
    return lambda f: isinstance(f.message, (mg.Ack, mg.Nack)) and f.message.msg_id == cls.ID


def _mission(to_rover=(), to_host=()):
    host_end, rover_end = PipeTransport.pair()
    lossy = LossyEnd(host_end, to_rover, to_host)
    rover = CoreRover(rover_end, boot_id=7)
    notes: list[str] = []
    mission = Mission(
        Link(lossy),
        OccupancyGrid(2.36, 1.75, PlannerConfig()),
        (0.3, 0.3),
        (2.0, 1.4),
        on_event=lambda t, text: notes.append(text),
    )
    return mission, rover, notes


def _run(mission, rover, seconds, t0=0.0, until=None):
    t = t0
    while t < t0 + seconds and not mission.finished and not (until and until()):
        mission.on_detection(Detection(t - 0.04, 0.3, 0.3, 0.0), t)
        mission.tick(t)
        rover.serve(t)
        t = round(t + 0.03, 6)
    return t


def _started(rover) -> bool:
    return rover.core.probe().state in (mg.RoverState.SCAN, mg.RoverState.ROTATE, mg.RoverState.DRIVE)


# ------------------------------------------------------------------ the handshake


def test_a_lost_host_hello_is_said_again_and_the_mission_goes_on():
    # The host's first two HELLOs are lost: the rover's own HELLO (at boot) reaches the host,
    # which configures and loads; but the rover does not know this host: its STATUS lacks
    # schema_ok (and it would refuse START, schema_mismatch): the cue to say HELLO again.
    lost_hellos = Rule(is_(mg.Hello), nth=(1, 2))
    mission, rover, notes = _mission(to_rover=[lost_hellos])
    _run(mission, rover, 8.0, until=lambda: mission.phase is Phase.RUN)
    assert lost_hellos.applied == 2
    assert mission.phase is Phase.RUN and _started(rover), notes
    assert mission.hellos_again >= 1 and not mission.nacks


# ------------------------------------------------------------------ START


def test_a_lost_start_is_sent_again_and_taken_once():
    mission, rover, notes = _mission(to_rover=[Rule(is_(mg.Start))])
    _run(mission, rover, 5.0, until=lambda: mission.phase is Phase.RUN)
    assert mission.phase is Phase.RUN and _started(rover)
    assert len(rover.of(mg.Start)) == 1 and mission.sent_again.get("start") == 1


def test_a_lost_ack_of_start_sends_start_again_which_the_running_rover_acks_and_ignores():
    mission, rover, notes = _mission(to_host=[Rule(answers(mg.Start))])
    _run(mission, rover, 5.0, until=lambda: mission.phase is Phase.RUN)
    assert mission.phase is Phase.RUN and _started(rover)
    assert len(rover.of(mg.Start)) == 2  # the first taken, its ACK lost; the second ACKed
    assert sum(isinstance(m, mg.Ack) and m.msg_id == mg.Start.ID for m in rover.said) == 2


def test_a_duplicated_start_and_duplicated_chunks_change_nothing():
    mission, rover, notes = _mission(
        to_rover=[Rule(is_(mg.Start), action="dup"), Rule(is_(mg.Path), nth=range(1, 10), action="dup")]
    )
    _run(mission, rover, 5.0, until=lambda: mission.phase is Phase.RUN)
    assert mission.phase is Phase.RUN and _started(rover) and not mission.nacks


# ------------------------------------------------------------------ the path, chunk by chunk


def _path(n):
    return [(100 + 40 * i, 200 + 30 * i) for i in range(n)]


def _upload(upload: PathUpload, rover: CoreRover, lossy: LossyEnd, host: Link, seconds=10.0):
    """Drive an upload to the rover over the lossy pipe as the mission does: send what is due,
    take the answers, until the rover holds the whole path."""
    t = 0.0
    answers_seen = []
    while t < seconds and not upload.complete:
        for m in upload.due(t):
            upload.sent(m, host.send(m), t)
        rover.serve(t)
        while (f := host.recv(0)) is not None:
            a = upload.answer(f.message)
            if a is not Answer.NOT_OURS:
                answers_seen.append(a)
            if isinstance(f.message, mg.Event) and f.message.kind == mg.EventKind.PATH_ACCEPTED:
                upload.mark_complete()
        t = round(t + 0.01, 6)
    return answers_seen


def _upload_setup(to_rover=(), to_host=()):
    host_end, rover_end = PipeTransport.pair()
    lossy = LossyEnd(host_end, to_rover, to_host)
    return Link(lossy), lossy, CoreRover(rover_end, boot_id=7)


def _held_path(rover: CoreRover, upload: PathUpload):
    accepted = [m.arg for m in rover.said if isinstance(m, mg.Event) and m.kind == mg.EventKind.PATH_ACCEPTED]
    return upload.path_id in accepted


def test_a_lost_chunk_is_sent_again_and_the_load_resumes_there_not_from_the_start():
    # 20 waypoints: chunks at 0, 8, 16. The chunk at 8 is lost the first time: the rover takes
    # 0, refuses 16 (out_of_order, expecting 8), and the upload sends 8 and 16 again, never 0.
    host, lossy, rover = _upload_setup(to_rover=[Rule(is_(mg.Path, first_index=8))])
    upload = PathUpload(0x0101, _path(20), resend_s=0.4)
    seen = _upload(upload, rover, lossy, host)
    assert upload.complete and _held_path(rover, upload)
    firsts = [m.first_index for m in rover.of(mg.Path)]
    assert firsts == [0, 16, 8, 16]  # what reached the rover: 8 lost once, 0 never again
    assert Answer.RESUME in seen and upload.frames_resent == 2


def test_a_lost_ack_of_a_chunk_costs_nothing_when_a_later_chunk_is_acked():
    host, lossy, rover = _upload_setup(to_host=[Rule(answers(mg.Path))])  # the ACK of chunk 0
    upload = PathUpload(0x0102, _path(20), resend_s=0.4)
    _upload(upload, rover, lossy, host)
    assert upload.complete and _held_path(rover, upload)
    assert [m.first_index for m in rover.of(mg.Path)] == [0, 8, 16] and upload.frames_resent == 0


def test_every_ack_lost_the_rover_acks_the_repeats_of_the_path_it_holds():
    # All three ACKs and the PATH_ACCEPTED event are lost: the upload sends every chunk again,
    # and the rover, holding that path whole, ACKs each repeat without starting it over.
    host, lossy, rover = _upload_setup(
        to_host=[
            Rule(answers(mg.Path), nth=(1, 2, 3)),
            Rule(lambda f: isinstance(f.message, mg.Event) and f.message.kind == mg.EventKind.PATH_ACCEPTED),
        ]
    )
    upload = PathUpload(0x0103, _path(20), resend_s=0.4)
    _upload(upload, rover, lossy, host)
    assert upload.complete and _held_path(rover, upload)
    accepted = [m for m in rover.said if isinstance(m, mg.Event) and m.kind == mg.EventKind.PATH_ACCEPTED]
    assert len(accepted) == 1  # taken once, not staged again by the repeats
    assert not any(isinstance(m, mg.Nack) for m in rover.said)


def test_a_chunk_lost_every_time_exhausts_its_attempts_without_flooding_the_line():
    host, lossy, rover = _upload_setup(to_rover=[Rule(is_(mg.Path, first_index=8), nth=range(1, 1000))])
    upload = PathUpload(0x0104, _path(20), resend_s=0.4)
    _upload(upload, rover, lossy, host, seconds=4.0)
    assert not upload.complete and upload.taken == 1
    # At most two attempts per 0.4 s (its resend time, and once more at once on the NACK that
    # says it was lost), not one per round trip.
    assert 8 <= upload.tries() <= 21
    assert len(rover.of(mg.Path)) < 60


def test_path_chunks_carry_the_waypoints_in_order():
    chunks = path_chunks(5, _path(17))
    assert [(c.first_index, c.count, c.total) for c in chunks] == [(0, 8, 17), (8, 8, 17), (16, 1, 17)]
    assert chunks[2].x_mm[0] == 100 + 40 * 16 and chunks[2].x_mm[1:] == (0,) * 7


# ------------------------------------------------------------------ STOP


def test_a_lost_stop_is_sent_again_until_the_rover_acks_it():
    mission, rover, notes = _mission(to_rover=[Rule(is_(mg.Stop))])
    t = _run(mission, rover, 5.0, until=lambda: mission.phase is Phase.RUN)
    assert _started(rover)
    mission.fail("an operator ends it")
    assert mission.done and not mission.finished
    _run(mission, rover, 3.0, t0=t)
    assert mission.finished and len(rover.of(mg.Stop)) == 1 and mission.sent_again.get("stop") == 1
    assert rover.core.probe().state == mg.RoverState.IDLE
