"""Hostile input to the link and the transports: a flood of frames or junk bytes never grows
memory without bound and never stretches a wait past its timeout; a bad timeout, retry count or
read size is a one-line InputError; any bytes on the line give frames or counted drops.

The rest of what was test_hostile_link.py: test_hostile_ports.py (transport specs),
test_hostile_map_files.py (learned-map files), test_hostile_cli.py (`rovernav run` and
`rovernav demo`)."""

from __future__ import annotations

import math
import os
import threading
import time
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.core_transport import firmware_hello

from rovernav.errors import InputError
from rovernav.link import link as link_mod
from rovernav.link import messages_gen as mg
from rovernav.link import transport as transport_mod
from rovernav.link.errors import LinkError, LinkTimeout
from rovernav.link.framing import MAX_ENCODED_BODY, FrameDecoder, encode_frame
from rovernav.link.link import MAX_PENDING_FRAMES, Link
from rovernav.link.requests import RequestTracker
from rovernav.link.transport import MAX_READ_BYTES, LoopbackTransport, PipeTransport

needs_pty = pytest.mark.skipif(os.name != "posix", reason="pseudo-terminals are POSIX only")

ROVER_HELLO = firmware_hello(boot_id=7)


class FakeClock:
    """The link's and the transports' clock, moving 1 ms each time the test's own thread reads it
    (a flooding thread sees it stand still): a wait's deadline is then a matter of the code's
    logic, not of how busy the test machine is."""

    TICK_S = 0.001

    def __init__(self):
        self.now = 1000.0
        self.owner = threading.get_ident()

    def monotonic(self) -> float:
        if threading.get_ident() == self.owner:
            self.now += self.TICK_S
        return self.now


@pytest.fixture
def clock(monkeypatch):
    fake = FakeClock()
    stand_in = SimpleNamespace(monotonic=fake.monotonic, sleep=time.sleep, time=time.time)
    monkeypatch.setattr(link_mod, "time", stand_in)
    monkeypatch.setattr(transport_mod, "time", stand_in)
    return fake


#: How far past its deadline a wait reads on: the link's late polls, and a few reads of the clock.
LATE_S = link_mod._LATE_POLL_S + 0.02


class Flooder:
    """A thread writing `burst` into a transport end as fast as it will take it, until stopped."""

    def __init__(self, end, burst: bytes) -> None:
        self.end, self.burst = end, burst
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.is_set():
            try:
                self.end.write(self.burst)
            except LinkTimeout:  # the reader's queue is full: it is bounded
                continue
            except LinkError:
                return

    def __enter__(self) -> Flooder:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.end.close()
        self.thread.join(3)


@pytest.fixture
def host_and_flood_end():
    a, b = PipeTransport.pair()
    host = Link(a)
    yield host, b
    host.close()
    b.close()


def status_burst(count: int = 256) -> bytes:
    return b"".join(encode_frame(mg.Ack(msg_id=mg.Config.ID, seq=i & 0xFF), i & 0xFF) for i in range(count))


def assert_bounded(host: Link) -> None:
    assert host.pending <= MAX_PENDING_FRAMES
    assert len(host._decoder._buf) <= MAX_ENCODED_BODY
    assert host.transport.buffered <= host.transport._rx.capacity


# ------------------------------------------------------------------ case 3: floods and timeouts


def test_handshake_under_a_flood_of_valid_non_hello_frames_times_out_in_time_with_bounded_memory(
    host_and_flood_end, monkeypatch, clock
):
    monkeypatch.setattr(link_mod, "MAX_PENDING_FRAMES", 64)  # the cap, met quickly
    host, end = host_and_flood_end
    with Flooder(end, status_burst()):
        started = clock.now
        with pytest.raises(LinkTimeout, match="no HELLO"):
            host.handshake(boot_id=1, timeout_s=0.4)
        took = clock.now - started
        assert 0.4 <= took < 0.4 + LATE_S
        assert host.pending == 64 and host.pending_dropped > 0
        assert host.counters.frames_ok > 64
        assert_bounded(host)


def test_handshake_under_a_flood_with_the_real_cap_keeps_at_most_max_pending_frames(host_and_flood_end):
    host, end = host_and_flood_end
    with Flooder(end, status_burst()):
        with pytest.raises(LinkTimeout):
            host.handshake(boot_id=1, timeout_s=0.6)
        assert_bounded(host)


def test_handshake_finds_the_rovers_hello_inside_a_flood(host_and_flood_end, clock):
    host, end = host_and_flood_end
    burst = status_burst(200) + encode_frame(ROVER_HELLO, 0) + status_burst(200)
    with Flooder(end, burst):
        started = clock.now
        hello = host.handshake(boot_id=1, timeout_s=2.0)
        assert clock.now - started < 2.0  # found, not timed out
        assert hello.boot_id == 7 and host.peer_hello == hello
        assert_bounded(host)


@pytest.mark.parametrize("junk", [b"\x55" * 4096, bytes(range(1, 256)) * 16, b"\x00" * 4096, b"\x02\x01\x00" * 1000])
def test_handshake_under_a_flood_of_junk_bytes_times_out_in_time_with_bounded_buffers(host_and_flood_end, junk, clock):
    host, end = host_and_flood_end
    with Flooder(end, junk):
        started = clock.now
        with pytest.raises(LinkTimeout):
            host.handshake(boot_id=1, timeout_s=0.3)
        assert 0.3 <= clock.now - started < 0.3 + LATE_S
        assert host.pending == 0
        assert_bounded(host)


def test_request_under_a_flood_times_out_in_time(host_and_flood_end, clock):
    host, end = host_and_flood_end
    with Flooder(end, status_burst()):  # ACKs, but none for what we ask
        started = clock.now
        with pytest.raises(LinkTimeout, match="STOP"):
            host.request(mg.Stop(), timeout_s=0.15, retries=1)
        assert 0.3 <= clock.now - started < 0.3 + 2 * LATE_S  # two attempts of 0.15 s
        assert_bounded(host)


def test_recv_with_a_timeout_returns_in_time_under_a_flood_of_junk(host_and_flood_end, clock):
    host, end = host_and_flood_end
    with Flooder(end, b"\x55" * 4096):
        started = clock.now
        assert host.recv(timeout_s=0.2) is None
        assert 0.2 <= clock.now - started < 0.2 + LATE_S


BAD_TIMEOUTS = [math.nan, math.inf, -math.inf, -1.0, -1e-9, 1e300, 10**400, True, "1", None]


@pytest.mark.parametrize("timeout_s", BAD_TIMEOUTS)
def test_handshake_refuses_a_timeout_that_is_not_finite_and_positive(timeout_s):
    with Link(LoopbackTransport()) as link:
        with pytest.raises(InputError, match="timeout_s"):
            link.handshake(boot_id=1, timeout_s=timeout_s)
        assert link.tx_frames == 0  # refused before anything was sent


@pytest.mark.parametrize("timeout_s", [t for t in BAD_TIMEOUTS if t is not None])
def test_recv_request_and_read_refuse_a_bad_timeout(timeout_s):
    with Link(LoopbackTransport()) as link:
        with pytest.raises(InputError, match="timeout_s"):
            link.recv(timeout_s=timeout_s)
        with pytest.raises(InputError, match="timeout_s"):
            link.request(mg.Stop(), timeout_s=timeout_s)
        with pytest.raises(InputError, match="timeout_s"):
            link.transport.read(10, timeout_s)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"retries": math.nan}, "retries"),
        ({"retries": 10**9}, "retries"),
        ({"retries": 1.5}, "retries"),
    ],
)
def test_request_refuses_bad_retries(kwargs, words):
    with Link(LoopbackTransport()) as link:
        with pytest.raises(InputError, match=words):
            link.request(mg.Stop(), timeout_s=0.1, **kwargs)


@pytest.mark.parametrize("resend", [0, -1, math.nan, math.inf])
def test_a_link_refuses_a_bad_hello_resend_interval(resend):
    with pytest.raises(InputError, match="hello_resend_s"):
        Link(LoopbackTransport(), hello_resend_s=resend)


@pytest.mark.parametrize("max_bytes", [0, -5, 1.5, math.nan, "10", None])
def test_read_refuses_a_bad_max_bytes(max_bytes):
    with LoopbackTransport() as t:
        with pytest.raises(InputError, match="max_bytes"):
            t.read(max_bytes, 0)


def test_a_huge_max_bytes_reads_at_most_max_read_bytes():
    with LoopbackTransport(capacity_bytes=2 * MAX_READ_BYTES) as t:
        t.write(b"x" * (MAX_READ_BYTES + 10))
        assert len(t.read(10**15, 0)) == MAX_READ_BYTES


def test_the_decoder_holds_at_most_one_frame_of_bytes_however_long_the_run_without_a_delimiter():
    d = FrameDecoder()
    for _ in range(50):
        assert d.feed(b"\x55" * 100_000) == []
        assert len(d._buf) <= MAX_ENCODED_BODY
    frames = d.feed(b"\x00" + encode_frame(mg.Stop(), 3))
    assert [f.seq for f in frames] == [3] and d.counters.overlong == 1


def test_a_loopback_nobody_reads_refuses_more_than_its_capacity_after_its_write_timeout():
    with LoopbackTransport(capacity_bytes=1000, write_timeout_s=0.1) as t:
        t.write(b"a" * 1000)
        started = time.monotonic()
        with pytest.raises(LinkTimeout, match="nobody is reading"):
            t.write(b"b")
        assert time.monotonic() - started >= 0.1  # it waited its timeout for room, then gave up
        assert t.buffered == 1000


def test_a_pipe_writer_waits_for_room_and_then_everything_arrives_in_order():
    a, b = PipeTransport.pair(capacity_bytes=64, write_timeout_s=2.0)
    data = bytes(range(256)) * 40
    got = bytearray()

    def reader():
        while len(got) < len(data):
            got.extend(b.read(50, 1.0))

    t = threading.Thread(target=reader)
    t.start()
    a.write(data)  # 160 times the capacity: waits for the reader, never grows past 64 bytes
    t.join(5)
    assert bytes(got) == data
    a.close()
    b.close()


def test_an_unanswered_request_resent_forever_keeps_at_most_256_sequence_numbers():
    t = RequestTracker(resend_s=0.1, max_tries=3)
    p = t.sent(mg.Stop(), seq=0, now_s=0.0)
    for i in range(1, 10_000):
        t.resent(p, i & 0xFF, now_s=i * 0.1, count=False)
    assert len(p.seqs) == 256 and len(set(p.seqs)) == 256 and p.seqs[-1] == 9_999 & 0xFF
    assert t.answer(mg.Ack(msg_id=mg.Stop.ID, seq=5)) is p


@pytest.mark.parametrize("resend_s, max_tries", [(math.nan, 1), (math.inf, 1), (1, 1.5), (1, math.nan)])
def test_a_request_tracker_refuses_non_finite_limits(resend_s, max_tries):
    with pytest.raises(InputError):
        RequestTracker(resend_s=resend_s, max_tries=max_tries)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=300), max_size=20))
def test_any_bytes_on_the_line_give_frames_or_counted_drops_never_an_exception(chunks):
    with Link(LoopbackTransport()) as link:
        for chunk in chunks:
            link.transport.write(chunk)
            while link.recv(timeout_s=0) is not None:
                pass
            assert len(link._decoder._buf) <= MAX_ENCODED_BODY
