"""The Link: sequenced frames, tolerance of split and corrupt input, requests and the HELLO handshake."""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable

import pytest

import rovernav
from rovernav.link.errors import LinkClosed, LinkTimeout, Nacked, SchemaMismatch
from rovernav.link.framing import cobs_encode, crc16, encode_frame
from rovernav.link.link import Link, host_hello, version_word
from rovernav.link.messages_gen import (
    MESSAGES,
    PROTOCOL_VERSION,
    SCHEMA_HASH,
    Ack,
    Config,
    Event,
    EventKind,
    Fix,
    Heartbeat,
    Hello,
    LinkAuth,
    Nack,
    NackReason,
    Obstacle,
    Param,
    Path,
    Provision,
    Role,
    RoverState,
    Start,
    Status,
    Stop,
    StopReason,
)
from rovernav.link.schema import Message
from rovernav.link.transport import LoopbackTransport, PipeTransport, Transport

# one of each message, with values away from zero and at the ends of their ranges
SAMPLES: list[Message] = [
    Hello(schema_hash=0xFFFFFFFF, boot_id=0xCAFEBABE, firmware_version=0x0102, role=Role.ROVER, max_waypoints=32),
    Heartbeat(host_time_ms=4_000_000_000, camera=2),
    Fix(x_mm=-32768, y_mm=32767, heading_cdeg=-17999, age_ms=120, sd_mm=255, frame_seq=65535),
    Path(
        path_id=7,
        total=20,
        first_index=8,
        count=8,
        x_mm=(-400, -300, -200, -100, 0, 100, 200, 300),
        y_mm=(1, -2, 3, -4, 5, -6, 7, -8),
    ),
    Start(path_id=0xFFFF),
    Stop(reason=StopReason.REPLANNING),
    Config(param=Param.PID_KP_X100, value=-300),
    Status(
        time_ms=123_456,
        state=RoverState.DRIVE,
        flags=0x81,
        fault=0,
        path_id=7,
        waypoint_index=3,
        x_mm=-1500,
        y_mm=900,
        heading_cdeg=9000,
        sd_x_mm=12,
        sd_y_mm=13,
        corr_xy_permille=-250,
        sd_heading_cdeg=150,
        dr_distance_mm=300,
        fix_age_ms=65535,
        left_pwm=-255,
        right_pwm=255,
        rx_ok=65535,
        rx_bad_crc=1,
        rx_overlong=2,
        rx_unknown_id=3,
        rx_malformed=4,
    ),
    Obstacle(scan_id=3, bearing_cdeg=-4500, range_mm=380, x_mm=100, y_mm=-200, heading_cdeg=18000, sd_mm=25),
    Ack(msg_id=Start.ID, seq=255),
    Nack(msg_id=Path.ID, seq=0, reason=NackReason.OUT_OF_ORDER, detail=65535),
    Event(kind=EventKind.REPLANNED, arg=4, time_ms=0xFFFFFFFF, x_mm=-1, y_mm=1),
    Provision(key=tuple(range(240, 256)), erase=1),
    LinkAuth(signing=1, bad_tag=65535, replayed=7, not_signed=1, unverified=0),
]


@pytest.fixture
def pipe():
    """(host Link, rover Link) over an in-process pipe; both closed afterwards."""
    a, b = PipeTransport.pair()
    host, rover = Link(a), Link(b)
    yield host, rover
    rover.close()
    host.close()


class FakeRover:
    """A thread that answers each frame it receives with answer(frame) -> messages to send."""

    def __init__(self, transport: Transport, answer: Callable[[Link, object], list[Message]]) -> None:
        self.link = Link(transport)
        self.answer = answer
        self.seen: list = []
        self.errors: list[BaseException] = []
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while True:
                frame = self.link.recv(timeout_s=None)
                self.seen.append(frame)
                for reply in self.answer(self.link, frame):
                    self.link.send(reply)
        except LinkClosed:
            pass
        except BaseException as exc:  # noqa: BLE001 - reported by stop()
            self.errors.append(exc)

    def stop(self) -> list:
        """Close the rover's end, wait for the thread, and return the frames it saw."""
        self.link.close()
        self._thread.join(1.0)
        assert not self._thread.is_alive()
        assert not self.errors, self.errors
        return self.seen


@pytest.fixture
def host_and_rover_end():
    """A host Link and the transport for a FakeRover at the other end of a pipe."""
    a, b = PipeTransport.pair()
    host = Link(a)
    yield host, b
    b.close()
    host.close()


def take(link: Link, count: int, timeout_s: float = 1.0) -> list:
    """The next count frames, each awaited at most timeout_s [s] (a bound, never a wait)."""
    frames = []
    for _ in range(count):
        frame = link.recv(timeout_s)
        assert frame is not None, f"only {len(frames)} of {count} frames arrived"
        frames.append(frame)
    return frames


def ack(frame) -> Ack:
    return Ack(msg_id=frame.msg_id, seq=frame.seq)


def rover_hello(schema_hash: int = SCHEMA_HASH) -> Hello:
    from tests.core_transport import firmware_hello

    return firmware_hello(schema_hash=schema_hash, boot_id=0x1234)


# ------------------------------------------------------------------ send and receive


def test_the_samples_cover_every_message_in_the_protocol():
    assert {type(m) for m in SAMPLES} == set(MESSAGES.values())


@pytest.mark.parametrize("message", SAMPLES, ids=lambda m: m.NAME)
def test_every_message_type_arrives_intact_with_its_sequence_number(pipe, message):
    host, rover = pipe
    seq = host.send(message)
    frame = rover.recv(timeout_s=1.0)
    assert frame is not None
    assert (frame.msg_id, frame.seq, frame.message) == (message.ID, seq, message)
    assert frame.payload == message.pack()


def test_all_messages_sent_in_a_burst_arrive_in_order_both_ways(pipe):
    host, rover = pipe
    for message in SAMPLES:
        host.send(message)
        rover.send(message)
    assert [f.message for f in take(rover, len(SAMPLES))] == SAMPLES
    assert [f.message for f in take(host, len(SAMPLES))] == SAMPLES
    assert rover.recv(timeout_s=0) is None and host.recv(timeout_s=0) is None


def test_sequence_numbers_count_up_from_zero_and_wrap_after_255(pipe):
    host, rover = pipe
    seqs = [host.send(Heartbeat(host_time_ms=i)) for i in range(258)]
    assert seqs == list(range(256)) + [0, 1]
    received = list(rover.messages(timeout_s=0))  # all written already: no need to wait
    assert [f.seq for f in received] == seqs
    assert [f.message.host_time_ms for f in received] == list(range(258))


def test_byte_and_frame_counters_add_up(pipe):
    host, rover = pipe
    for message in SAMPLES:
        host.send(message)
    list(rover.messages(timeout_s=0))
    expected_bytes = sum(len(encode_frame(m, i)) for i, m in enumerate(SAMPLES))
    assert host.tx_frames == len(SAMPLES)
    assert host.tx_bytes == expected_bytes
    assert rover.rx_bytes == expected_bytes
    assert rover.counters.frames_ok == len(SAMPLES)
    assert rover.counters.dropped == 0


def test_a_message_with_a_bad_field_is_refused_before_anything_is_sent(pipe):
    host, rover = pipe
    with pytest.raises(ValueError, match="x_mm"):
        host.send(Fix(x_mm=40_000))
    assert (host.tx_frames, host.tx_bytes) == (0, 0)
    assert host.send(Fix()) == 0  # the refused message used no sequence number
    assert rover.recv(timeout_s=1.0).message == Fix()


def test_recv_without_waiting_returns_every_frame_already_there_even_past_one_read(pipe):
    host, rover = pipe
    fixes = [Fix(x_mm=i, frame_seq=i) for i in range(500)]  # several READ_CHUNK_BYTES of frames
    for fix in fixes:
        host.send(fix)
    assert host.tx_bytes > 4096
    assert [f.message for f in rover.messages(timeout_s=0)] == fixes


def test_messages_keeps_yielding_while_frames_keep_coming(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(end, lambda link, frame: [Event(kind=EventKind.SCAN_DONE, arg=i) for i in range(3)])
    host.send(Stop())
    got = []
    for frame in host.messages(timeout_s=1.0):
        got.append(frame.message.arg)
        if len(got) == 3:
            break
    assert got == [0, 1, 2]
    rover.stop()


def test_recv_returns_none_when_nothing_arrives_in_time(pipe):
    host, _ = pipe
    assert host.recv(timeout_s=0) is None
    assert host.recv(timeout_s=0.02) is None
    assert list(host.messages(timeout_s=0.02)) == []


def test_recv_rejects_a_negative_timeout(pipe):
    host, _ = pipe
    with pytest.raises(ValueError, match="-1"):
        host.recv(timeout_s=-1)


def test_a_link_on_a_loopback_hears_itself():
    with Link(LoopbackTransport()) as link:
        link.send(Stop(reason=StopReason.OPERATOR))
        frame = link.recv(timeout_s=1.0)
        assert frame.message == Stop(reason=StopReason.OPERATOR)
    assert link.transport.closed


def test_sends_from_many_threads_get_distinct_sequence_numbers_and_all_arrive(pipe):
    host, rover = pipe
    seqs: list[int] = []
    lock = threading.Lock()

    def stream(thread_no: int) -> None:
        for i in range(50):
            seq = host.send(Fix(x_mm=thread_no, frame_seq=i))
            with lock:
                seqs.append(seq)

    threads = [threading.Thread(target=stream, args=(n,)) for n in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(1.0)
    assert sorted(seqs) == list(range(200))
    received = list(rover.messages(timeout_s=0))
    assert sorted(f.seq for f in received) == list(range(200))
    for n in range(4):  # each thread's fixes stay in its own order
        assert [f.message.frame_seq for f in received if f.message.x_mm == n] == list(range(50))
    assert rover.counters.dropped == 0


# ------------------------------------------------------------------ split and corrupt input


class OneByteAtATime(Transport):
    """Wraps a transport so that every read returns at most one byte."""

    def __init__(self, inner: Transport) -> None:
        super().__init__(f"one-byte({inner.name})")
        self.inner = inner

    def _write(self, data: bytes) -> None:
        self.inner.write(data)

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        return self.inner.read(1, timeout_s)

    def _close(self) -> None:
        self.inner.close()


def test_frames_split_into_single_bytes_still_decode():
    inner = LoopbackTransport()
    link = Link(OneByteAtATime(inner))
    stream = b"".join(encode_frame(m, i) for i, m in enumerate(SAMPLES))
    inner.write(stream)
    received = list(link.messages(timeout_s=0))
    assert [f.message for f in received] == SAMPLES
    assert link.rx_bytes == len(stream)
    link.close()


def _raw_frame(body_without_crc: bytes) -> bytes:
    body = body_without_crc + crc16(body_without_crc).to_bytes(2, "little")
    return cobs_encode(body) + b"\x00"


def _bad_crc_frame() -> bytes:
    body = bytes((PROTOCOL_VERSION, Fix.ID, 0)) + Fix(x_mm=1).pack()
    wrong_crc = crc16(body) ^ 0x5555
    return cobs_encode(body + wrong_crc.to_bytes(2, "little")) + b"\x00"


# each kind of garbage ends in a delimiter, so the decoder is back in step for the next frame
GARBAGE = [
    (b"\xff" * 200 + b"\x00", "overlong"),
    (b"hello\x00", "malformed"),  # not valid COBS
    (b"\x02\x01\x00", "malformed"),  # too short for a header and CRC
    (_raw_frame(bytes((PROTOCOL_VERSION + 1, Fix.ID, 0)) + Fix().pack()), "malformed"),  # wrong version
    (_raw_frame(bytes((PROTOCOL_VERSION, Fix.ID, 0)) + Fix().pack()[:-1]), "malformed"),  # short payload
    (_raw_frame(bytes((PROTOCOL_VERSION, 0x7E, 0)) + b"\x01\x02"), "unknown_id"),
    (_bad_crc_frame(), "bad_crc"),
]


@pytest.mark.parametrize("garbage, counter", GARBAGE, ids=[g[1] + str(i) for i, g in enumerate(GARBAGE)])
def test_garbage_between_frames_is_counted_and_dropped_while_good_frames_arrive(garbage, counter):
    transport = LoopbackTransport()
    link = Link(transport)
    good = [Fix(x_mm=i, y_mm=-i) for i in range(5)]
    for i, message in enumerate(good):
        transport.write(garbage)
        transport.write(encode_frame(message, i))
    transport.write(garbage)
    assert [f.message for f in link.messages(timeout_s=0)] == good
    counters = dataclasses.asdict(link.counters)
    assert counters.pop("frames_ok") == len(good)
    assert counters.pop(counter) == len(good) + 1
    assert set(counters.values()) == {0}
    link.close()


def test_all_kinds_of_garbage_mixed_in_one_stream_are_each_counted():
    transport = LoopbackTransport()
    link = Link(transport)
    good = [Event(kind=EventKind.WAYPOINT_REACHED, arg=i) for i in range(len(GARBAGE))]
    for i, (garbage, _) in enumerate(GARBAGE):
        transport.write(garbage + encode_frame(good[i], i))
    assert [f.message for f in link.messages(timeout_s=0)] == good
    c = link.counters
    assert (c.frames_ok, c.overlong, c.malformed, c.unknown_id, c.bad_crc) == (len(good), 1, 4, 1, 1)
    link.close()


def test_a_frame_glued_to_undelimited_noise_is_lost_but_the_decoder_resynchronises():
    transport = LoopbackTransport()
    link = Link(transport)
    transport.write(b"\x13\x37noise" + encode_frame(Fix(x_mm=1), 0) + encode_frame(Fix(x_mm=2), 1))
    assert [f.message for f in link.messages(timeout_s=0)] == [Fix(x_mm=2)]
    assert link.counters.dropped == 1
    link.close()


# ------------------------------------------------------------------ request


def test_request_returns_the_matching_ack(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(end, lambda link, frame: [ack(frame)])
    reply = host.request(Start(path_id=3), timeout_s=1.0)
    assert reply.message == Ack(msg_id=Start.ID, seq=0)
    seen = rover.stop()
    assert [f.message for f in seen] == [Start(path_id=3)]


def test_request_raises_nacked_with_the_rovers_reason(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(
        end, lambda link, frame: [Nack(msg_id=frame.msg_id, seq=frame.seq, reason=NackReason.NO_PATH, detail=0)]
    )
    with pytest.raises(Nacked) as info:
        host.request(Start(path_id=3), timeout_s=1.0)
    assert info.value.reason == NackReason.NO_PATH
    assert "start" in str(info.value) and "no_path" in str(info.value)
    rover.stop()


def test_request_raises_link_timeout_naming_the_message_after_resending_with_new_seqs(pipe):
    host, rover = pipe
    with pytest.raises(LinkTimeout, match="CONFIG") as info:
        host.request(Config(param=Param.DRIVE_PWM, value=70), timeout_s=0.03, retries=2)
    assert "3 attempts" in str(info.value)
    sent = list(rover.messages(timeout_s=0))
    assert [f.seq for f in sent] == [0, 1, 2]
    assert all(f.message == Config(param=Param.DRIVE_PWM, value=70) for f in sent)


def test_request_with_no_retries_sends_once(pipe):
    host, rover = pipe
    with pytest.raises(LinkTimeout, match="1 attempts"):
        host.request(Stop(), timeout_s=0.02, retries=0)
    assert len(list(rover.messages(timeout_s=0))) == 1


@pytest.mark.parametrize("timeout_s, retries", [(0, 2), (-1, 2), (1.0, -1)])
def test_request_rejects_bad_arguments(pipe, timeout_s, retries):
    host, _ = pipe
    with pytest.raises(ValueError):
        host.request(Stop(), timeout_s=timeout_s, retries=retries)


def test_request_succeeds_when_the_rover_answers_only_the_resend(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(end, lambda link, frame: [ack(frame)] if frame.seq > 0 else [])
    reply = host.request(Start(path_id=1), timeout_s=0.05, retries=2)
    assert reply.message == Ack(msg_id=Start.ID, seq=1)
    assert [f.seq for f in rover.stop()] == [0, 1]


def test_request_ignores_answers_to_other_messages_and_sequence_numbers(host_and_rover_end):
    host, end = host_and_rover_end

    def chatty(link, frame):
        return [
            Status(state=RoverState.IDLE),
            Ack(msg_id=Config.ID, seq=frame.seq),  # right seq, wrong message
            Nack(msg_id=frame.msg_id, seq=(frame.seq + 1) & 0xFF, reason=1, detail=0),  # wrong seq
            Obstacle(range_mm=250),
            ack(frame),
            Event(kind=EventKind.PATH_ACCEPTED, arg=3),
        ]

    rover = FakeRover(end, chatty)
    reply = host.request(Path(path_id=3, total=1, count=1), timeout_s=1.0)
    assert reply.message == Ack(msg_id=Path.ID, seq=0)
    # everything else the rover said is still there, in order
    rest = [f.message for f in take(host, 5)]
    rover.stop()
    assert rest == [
        Status(state=RoverState.IDLE),
        Ack(msg_id=Config.ID, seq=0),
        Nack(msg_id=Path.ID, seq=1, reason=1, detail=0),
        Obstacle(range_mm=250),
        Event(kind=EventKind.PATH_ACCEPTED, arg=3),
    ]


def test_frames_queued_before_a_request_come_out_first(host_and_rover_end):
    host, end = host_and_rover_end
    end.write(encode_frame(Status(time_ms=1), 0) + encode_frame(Status(time_ms=2), 1))
    # a first request reads past both statuses and queues them
    rover = FakeRover(end, lambda link, frame: [Status(time_ms=3), ack(frame)])
    host.request(Start(path_id=1), timeout_s=1.0)
    assert [f.message.time_ms for f in take(host, 3)] == [1, 2, 3]
    rover.stop()


def test_frames_arriving_across_several_requests_are_all_kept(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(end, lambda link, frame: [Event(kind=EventKind.WAYPOINT_REACHED, arg=frame.seq), ack(frame)])
    for path_id in range(5):
        host.request(Start(path_id=path_id), timeout_s=1.0)
    assert [f.message.arg for f in take(host, 5)] == [0, 1, 2, 3, 4]
    rover.stop()


# ------------------------------------------------------------------ handshake


def test_version_word_is_major_times_256_plus_minor():
    assert version_word("0.1.0") == 1
    assert version_word("1.2.3") == 258
    assert version_word("2.10") == 522
    # The host says the package's version, the one in pyproject.toml.
    import tomllib
    from pathlib import Path

    declared = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]["version"]
    major, minor = (int(part) for part in declared.split(".")[:2])
    assert rovernav.__version__ == declared
    assert host_hello(1).firmware_version == version_word(rovernav.__version__) == major * 256 + minor
    for bad in ("", "1", "x.y", "256.0", "1.256"):
        with pytest.raises(ValueError):
            version_word(bad)


def _answer_hello(schema_hash: int = SCHEMA_HASH):
    def answer(link, frame):
        if isinstance(frame.message, Hello) and frame.message.role == Role.HOST:
            return [rover_hello(schema_hash)]
        return []

    return answer


def test_handshake_returns_the_rovers_hello_after_sending_ours(host_and_rover_end):
    host, end = host_and_rover_end
    rover = FakeRover(end, _answer_hello())
    theirs = host.handshake(boot_id=0xB007, timeout_s=1.0)
    assert theirs == rover_hello()
    assert host.peer_hello == theirs
    seen = rover.stop()
    ours = seen[0].message
    assert ours == Hello(
        schema_hash=SCHEMA_HASH,
        boot_id=0xB007,
        firmware_version=version_word(rovernav.__version__),
        role=Role.HOST,
        max_waypoints=0,
    )


def test_handshake_raises_schema_mismatch_naming_both_hashes(host_and_rover_end):
    host, end = host_and_rover_end
    other = 0xDEADBEEF
    rover = FakeRover(end, _answer_hello(other))
    with pytest.raises(SchemaMismatch) as info:
        host.handshake(boot_id=1, timeout_s=1.0)
    assert (info.value.ours, info.value.theirs) == (SCHEMA_HASH, other)
    assert f"0x{other:08X}" in str(info.value)
    assert f"0x{SCHEMA_HASH:08X}" in str(info.value)
    assert host.peer_hello is None
    rover.stop()


def test_handshake_raises_link_timeout_when_no_rover_answers(pipe):
    host, rover = pipe
    with pytest.raises(LinkTimeout, match="no HELLO from the rover on pipe:a") as info:
        host.handshake(boot_id=1, timeout_s=0.05)
    assert "57600 baud" in str(info.value)
    assert all(f.message.role == Role.HOST for f in rover.messages(timeout_s=0))


def test_handshake_repeats_its_hello_for_a_rover_that_missed_the_first(host_and_rover_end):
    host, end = host_and_rover_end
    hellos = []

    def booting_rover(link, frame):
        hellos.append(frame)
        return [rover_hello()] if len(hellos) >= 2 else []  # still in its bootloader for the first

    rover = FakeRover(end, booting_rover)
    host.hello_resend_s = 0.02
    assert host.handshake(boot_id=1, timeout_s=1.0) == rover_hello()
    assert len(rover.stop()) >= 2


def test_handshake_does_not_take_its_own_echo_for_the_rovers_hello():
    with Link(LoopbackTransport()) as link:
        with pytest.raises(LinkTimeout):
            link.handshake(boot_id=1, timeout_s=0.05)


def test_frames_arriving_during_the_handshake_are_kept(host_and_rover_end):
    host, end = host_and_rover_end

    def answer(link, frame):
        return [Event(kind=EventKind.BOOT, arg=1), Status(state=RoverState.IDLE), rover_hello()]

    rover = FakeRover(end, answer)
    host.handshake(boot_id=1, timeout_s=1.0)
    kept = [f.message for f in take(host, 2)]
    rover.stop()
    assert kept[:2] == [Event(kind=EventKind.BOOT, arg=1), Status(state=RoverState.IDLE)]
