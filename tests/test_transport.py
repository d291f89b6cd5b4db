"""Transports: every kind moves bytes the same way, fails the same way, and is picked by name."""

from __future__ import annotations

import os
import threading
import time

import pytest

from rovernav.link import transport as transport_mod
from rovernav.link.errors import LinkClosed, PortError
from rovernav.link.framing import encode_frame
from rovernav.link.link import Link
from rovernav.link.messages_gen import Ack, Fix, Hello, Obstacle, Path, Role, Status
from rovernav.link.transport import (
    DEFAULT_BAUD,
    LoopbackTransport,
    PipeTransport,
    PtyTransport,
    SerialTransport,
    Transport,
    open_transport,
    parse_serial_spec,
)

needs_pty = pytest.mark.skipif(os.name != "posix", reason="pseudo-terminals are POSIX only")

# every byte value, including the delimiter and the bytes a cooked tty would swallow or
# translate (^C, ^S/^Q flow control, CR/LF, DEL): raw mode must pass them all untouched
ALL_BYTES = bytes(range(256)) + b"\x00\r\n\x03\x11\x13\x7f" + bytes(range(255, -1, -1))

MISSING_PORT = "COM250" if os.name == "nt" else "/dev/ttyROVERNAV_NO_SUCH_PORT"


def read_exactly(t: Transport, count: int, timeout_s: float = 1.0) -> bytes:
    """Read until count bytes came or timeout_s passed (an upper bound, not a wait)."""
    out = bytearray()
    deadline = time.monotonic() + timeout_s
    while len(out) < count:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        out += t.read(count - len(out), timeout_s=left)
    return bytes(out)


def loopback_ends():
    t = LoopbackTransport()
    return t, t, [t]


def pipe_ends():
    a, b = PipeTransport.pair()
    return a, b, [a, b]


def pipe_ends_reversed():
    a, b = PipeTransport.pair()
    return b, a, [a, b]


def pty_to_serial_ends():
    pty = PtyTransport()
    serial = SerialTransport(pty.peer_name)
    return pty, serial, [serial, pty]


def serial_to_pty_ends():
    pty = PtyTransport()
    serial = SerialTransport(pty.peer_name)
    return serial, pty, [serial, pty]


END_MAKERS = [
    pytest.param(loopback_ends, id="loopback"),
    pytest.param(pipe_ends, id="pipe a->b"),
    pytest.param(pipe_ends_reversed, id="pipe b->a"),
    pytest.param(pty_to_serial_ends, id="pty->serial", marks=needs_pty),
    pytest.param(serial_to_pty_ends, id="serial->pty", marks=needs_pty),
]


@pytest.fixture(params=END_MAKERS)
def ends(request):
    """(writer, reader) of one transport kind; everything is closed afterwards."""
    writer, reader, to_close = request.param()
    yield writer, reader
    for t in to_close:
        t.close()


# ------------------------------------------------------------------ the common contract


def test_every_transport_delivers_every_byte_value_in_order(ends):
    writer, reader = ends
    writer.write(ALL_BYTES)
    assert read_exactly(reader, len(ALL_BYTES)) == ALL_BYTES


def test_every_transport_keeps_order_across_many_small_writes(ends):
    writer, reader = ends
    chunks = [bytes([i]) * (i % 7 + 1) for i in range(100)]
    for chunk in chunks:
        writer.write(chunk)
    expected = b"".join(chunks)
    assert read_exactly(reader, len(expected)) == expected


def test_a_read_with_nothing_to_read_returns_empty_bytes_at_the_timeout(ends):
    _, reader = ends
    assert reader.read(timeout_s=0) == b""
    assert reader.read(timeout_s=0.01) == b""


def test_a_read_never_returns_more_than_max_bytes(ends):
    writer, reader = ends
    writer.write(b"abcdefgh")
    first = read_exactly(reader, 3)
    assert first == b"abc"
    assert read_exactly(reader, 5) == b"defgh"


def test_a_read_returns_what_is_available_without_waiting_for_max_bytes(ends):
    writer, reader = ends
    writer.write(b"xy")
    got = read_exactly(reader, 2)
    assert got == b"xy"
    # asking for more than is there comes back short, after the timeout, not never
    assert reader.read(4096, timeout_s=0.01) == b""


def test_writing_nothing_is_allowed_and_sends_nothing(ends):
    writer, reader = ends
    writer.write(b"")
    assert reader.read(timeout_s=0.01) == b""


@pytest.mark.parametrize("make", END_MAKERS)
def test_a_closed_transport_refuses_reads_and_writes(make):
    writer, reader, to_close = make()
    for t in to_close:
        t.close()
        t.close()  # closing twice is harmless
        assert t.closed
        with pytest.raises(LinkClosed):
            t.write(b"x")
        with pytest.raises(LinkClosed):
            t.read(timeout_s=0)


@pytest.mark.parametrize("make", END_MAKERS)
def test_a_transport_closes_at_the_end_of_a_with_block(make):
    writer, reader, to_close = make()
    for t in to_close:
        with t as entered:
            assert entered is t
            assert not t.closed
        assert t.closed


@pytest.mark.parametrize("max_bytes, timeout_s", [(0, 0), (-1, 0), (10, -0.5)])
def test_read_rejects_bad_arguments_with_the_value_in_the_message(max_bytes, timeout_s):
    with LoopbackTransport() as t:
        with pytest.raises(ValueError, match=str(max_bytes if max_bytes < 1 else timeout_s)):
            t.read(max_bytes, timeout_s)


def test_transport_names_say_what_they_are():
    with LoopbackTransport() as t:
        assert str(t) == "loop://"
        assert "LoopbackTransport" in repr(t)
    a, b = PipeTransport.pair("sim")
    assert (a.name, b.name) == ("sim:a", "sim:b")
    a.close()
    b.close()


# ------------------------------------------------------------------ in-process pipe


def test_a_pipe_end_reads_what_is_left_then_reports_the_other_end_closed():
    a, b = PipeTransport.pair()
    a.write(b"last words")
    a.close()
    assert read_exactly(b, 10) == b"last words"
    with pytest.raises(LinkClosed, match="other end"):
        b.read(timeout_s=0)
    with pytest.raises(LinkClosed, match="other end"):
        b.write(b"anyone?")
    b.close()


@pytest.mark.parametrize("close_which", ["own end", "other end"])
def test_closing_a_pipe_wakes_a_reader_blocked_without_timeout(close_which):
    a, b = PipeTransport.pair()
    outcome: list[BaseException] = []
    started = threading.Event()

    def reader():
        started.set()
        try:
            b.read(timeout_s=None)
        except BaseException as exc:  # noqa: BLE001 - recorded for the assertion below
            outcome.append(exc)

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    started.wait(1.0)
    (b if close_which == "own end" else a).close()
    thread.join(1.0)
    assert not thread.is_alive()
    assert len(outcome) == 1 and isinstance(outcome[0], LinkClosed)
    a.close()
    b.close()


def test_a_pipe_carries_bytes_written_from_many_threads_without_losing_any():
    a, b = PipeTransport.pair()
    writers = [threading.Thread(target=lambda: [a.write(b"z" * 10) for _ in range(100)]) for _ in range(4)]
    for w in writers:
        w.start()
    for w in writers:
        w.join(1.0)
    assert read_exactly(b, 4000) == b"z" * 4000
    assert b.read(timeout_s=0) == b""
    a.close()
    b.close()


# ------------------------------------------------------------------ pseudo-terminal and serial


@needs_pty
def test_a_pty_names_a_peer_device_that_exists():
    with PtyTransport() as pty:
        assert os.path.exists(pty.peer_name)
        assert pty.peer_name in pty.name


@needs_pty
def test_a_serial_transport_on_a_pty_peer_exchanges_frames_both_ways():
    samples_down = [
        Hello(schema_hash=1, boot_id=2, firmware_version=3, role=Role.HOST),
        Fix(x_mm=-5, y_mm=7),
        Path(path_id=9, total=8, first_index=0, count=8, x_mm=tuple(range(8)), y_mm=tuple(range(-8, 0))),
    ]
    samples_up = [
        Status(state=2, x_mm=-1000, rx_ok=65535),
        Obstacle(range_mm=321, bearing_cdeg=-4500),
        Ack(msg_id=4, seq=255),
    ]
    with PtyTransport() as pty, SerialTransport(pty.peer_name) as serial:
        assert serial.baud == DEFAULT_BAUD
        host, rover = Link(serial), Link(pty)
        for message in samples_down:
            seq = host.send(message)
            frame = rover.recv(timeout_s=1.0)
            assert frame is not None and (frame.message, frame.seq) == (message, seq)
        for message in samples_up:
            seq = rover.send(message)
            frame = host.recv(timeout_s=1.0)
            assert frame is not None and (frame.message, frame.seq) == (message, seq)
        assert host.counters.dropped == 0 and rover.counters.dropped == 0
        assert host.rx_bytes == rover.tx_bytes and rover.rx_bytes == host.tx_bytes


@needs_pty
def test_a_serial_transport_reports_its_device_gone_when_the_pty_closes():
    pty = PtyTransport()
    serial = SerialTransport(pty.peer_name)
    pty.close()
    with pytest.raises(LinkClosed, match=pty.peer_name):
        serial.read(timeout_s=0.5)
    serial.close()


@needs_pty
def test_closing_a_pty_wakes_a_reader_blocked_without_timeout():
    pty = PtyTransport()
    outcome: list[BaseException] = []
    started = threading.Event()

    def reader():
        started.set()
        try:
            pty.read(timeout_s=None)
        except BaseException as exc:  # noqa: BLE001 - recorded for the assertion below
            outcome.append(exc)

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    started.wait(1.0)
    pty.close()
    thread.join(1.0)
    assert not thread.is_alive()
    assert len(outcome) == 1 and isinstance(outcome[0], LinkClosed)


@needs_pty
def test_a_busy_port_raises_port_error_saying_so():
    with PtyTransport() as pty, SerialTransport(pty.peer_name):
        with pytest.raises(PortError, match="busy") as info:
            SerialTransport(pty.peer_name)
        assert pty.peer_name in str(info.value)


def test_a_missing_port_raises_port_error_naming_it_and_the_ports_that_exist(monkeypatch):
    monkeypatch.setattr(transport_mod, "available_ports", lambda: ["/dev/ttyFAKE0", "/dev/ttyFAKE1"])
    with pytest.raises(PortError) as info:
        SerialTransport(MISSING_PORT)
    message = str(info.value)
    assert MISSING_PORT in message
    assert "/dev/ttyFAKE0, /dev/ttyFAKE1" in message
    assert info.value.__cause__ is None  # no pyserial traceback chained on


def test_a_missing_port_on_a_machine_without_ports_says_none_were_found(monkeypatch):
    monkeypatch.setattr(transport_mod, "available_ports", lambda: [])
    with pytest.raises(PortError, match="No serial ports"):
        SerialTransport(MISSING_PORT)


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="needs /dev/null")
def test_a_file_that_is_not_a_serial_device_raises_port_error():
    with pytest.raises(PortError, match="/dev/null"):
        SerialTransport("/dev/null")


@pytest.mark.parametrize(
    "port, baud",
    [
        ("", 57600),
        ("  ", 57600),
        ("/dev/ttyUSB0", 0),
        ("/dev/ttyUSB0", -9600),
        ("/dev/ttyUSB0", "57600"),
        ("/dev/ttyUSB0", True),
    ],
)
def test_a_serial_transport_rejects_bad_settings_before_touching_the_port(port, baud):
    with pytest.raises(ValueError, match="port|baud"):
        SerialTransport(port, baud)


# ------------------------------------------------------------------ by name


def test_open_transport_makes_a_loopback_from_loop():
    with open_transport("loop://") as t:
        assert isinstance(t, LoopbackTransport)
        t.write(b"ping")
        assert read_exactly(t, 4) == b"ping"


@needs_pty
def test_open_transport_makes_a_pty_from_pty():
    with open_transport("pty://") as t:
        assert isinstance(t, PtyTransport)


@pytest.mark.parametrize("spec", [MISSING_PORT, MISSING_PORT + "@57600", MISSING_PORT + "@9600"])
def test_open_transport_of_a_missing_port_raises_port_error_naming_it(spec):
    with pytest.raises(PortError) as info:
        open_transport(spec)
    assert MISSING_PORT in str(info.value)


@needs_pty
def test_open_transport_opens_a_serial_port_at_the_baud_given():
    with PtyTransport() as pty, open_transport(f"{pty.peer_name}@115200") as t:
        assert isinstance(t, SerialTransport)
        assert t.baud == 115200


@pytest.mark.parametrize(
    "spec, port, baud",
    [
        ("/dev/ttyUSB0", "/dev/ttyUSB0", 57600),
        ("/dev/ttyUSB0@57600", "/dev/ttyUSB0", 57600),
        ("COM4@115200", "COM4", 115200),
        ("COM4", "COM4", 57600),
        ("/dev/serial/by-id/usb-FTDI@1@9600", "/dev/serial/by-id/usb-FTDI@1", 9600),
    ],
)
def test_a_serial_spec_splits_into_port_and_baud(spec, port, baud):
    assert parse_serial_spec(spec) == (port, baud)


@pytest.mark.parametrize(
    "spec, shown",
    [
        ("", "''"),
        ("   ", "'   '"),
        ("tcp://rover:5000", "tcp://rover:5000"),
        ("loop://extra", "loop://extra"),
        ("/dev/ttyUSB0@", "/dev/ttyUSB0@"),
        ("/dev/ttyUSB0@fast", "fast"),
        ("/dev/ttyUSB0@-5", "-5"),
        ("/dev/ttyUSB0@0", "/dev/ttyUSB0@0"),
        ("@57600", "@57600"),
    ],
)
def test_open_transport_rejects_a_bad_spec_naming_it(spec, shown):
    with pytest.raises(ValueError) as info:
        open_transport(spec)
    assert shown in str(info.value)


def test_open_transport_rejects_a_spec_that_is_not_a_string():
    with pytest.raises(ValueError, match="None"):
        open_transport(None)  # type: ignore[arg-type]


def test_link_frames_fit_through_every_transport_kind_unchanged(ends):
    writer, reader = ends
    frame = encode_frame(Fix(x_mm=1, y_mm=-1, heading_cdeg=18000), 42)
    writer.write(frame)
    assert read_exactly(reader, len(frame)) == frame
