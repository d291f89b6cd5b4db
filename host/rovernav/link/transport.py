"""Byte transports: one API for a serial port, a pseudo-terminal, a loopback and an in-process pipe.

The code above a transport (the Link, the mission) never knows which one it has. Every
transport offers the same contract:

    write(data)                  send all of data, or raise; never a short write
    read(max_bytes, timeout_s)   what is available now, up to max_bytes; if nothing is, wait
                                 at most timeout_s seconds for the first byte (None = no limit,
                                 0 = just poll) and return b"" if none came. A short read is
                                 normal: it means that was all that had arrived.
    close()                      idempotent; afterwards write and read raise LinkClosed
    closed                       True once closed

A read or write also raises LinkClosed when the other end went away (a pipe peer closed, a
serial device unplugged). Bytes already received are still returned before that.

Pick a transport from a string with open_transport():

    loop://                    LoopbackTransport: what is written is read back
    pty://                     PtyTransport: a pseudo-terminal; another program opens .peer_name
    /dev/ttyUSB0, COM4         SerialTransport at 57,600 baud 8N1
    /dev/ttyUSB0@115200        ... at another baud rate

A spec that cannot name anything (blank, control characters, longer than MAX_SPEC_CHARS, an
unknown scheme such as tcp:// or loop://x, a baud rate outside MIN_BAUD..MAX_BAUD) raises
PortSpecError (an InputError and a PortError) before any device is touched; a port that
cannot be opened (missing, busy, not a serial device) raises PortError. Bad arguments to
read() (a NaN, infinite or negative timeout) raise InputError.

Nothing here grows without bound: a read returns at most MAX_READ_BYTES, and the in-process
queues hold at most QUEUE_CAPACITY_BYTES (a writer then waits for the reader, as on a pty,
and raises LinkTimeout if nobody reads).
"""

from __future__ import annotations

import abc
import errno
import logging
import os
import select
import threading
import time
from types import TracebackType

from ..validate import check_number
from ..vehicle_gen import LINK_BAUD
from .errors import LinkClosed, LinkTimeout, PortError, PortSpecError

log = logging.getLogger("rovernav.link")

#: The radio's line rate (3DR 433 MHz telemetry radio) and the Uno's serial speed.
DEFAULT_BAUD = LINK_BAUD
#: Baud rates a spec may ask for: the slowest standard rate to the fastest USB-serial chips'.
MIN_BAUD, MAX_BAUD = 50, 4_000_000
#: Longest spec accepted (a device path; PATH_MAX is 4096 on Linux, 260 on Windows).
MAX_SPEC_CHARS = 1024
#: Largest single read: a larger max_bytes is allowed and reads at most this much (a short
#: read is normal), so no caller can make a read allocate without limit.
MAX_READ_BYTES = 1 << 20
#: Longest wait a read accepts [s] (None waits without limit); a longer or non-finite one is
#: refused rather than handed to select(), which would overflow.
MAX_TIMEOUT_S = 86_400.0
#: Bytes an in-process queue (loop://, a pipe) holds before its writer must wait for the reader:
#: three minutes of a 57,600-baud line, far more than any reader falls behind by.
QUEUE_CAPACITY_BYTES = 1 << 20


def check_timeout(name: str, timeout_s: float | None, hi: float = MAX_TIMEOUT_S) -> float | None:
    """`timeout_s` if it is None or a finite number of seconds in [0, hi]; else InputError naming it."""
    if timeout_s is None:
        return None
    if type(timeout_s) in (int, float) and 0 <= timeout_s <= hi:  # the common case, cheaply
        return timeout_s
    return check_number(f"{name} (seconds)", timeout_s, 0.0, hi)


class Transport(abc.ABC):
    """A bidirectional byte stream. Subclasses implement _write, _read and _close only."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._closed = False

    @property
    def name(self) -> str:
        """Human-readable description, used in error messages ("/dev/ttyUSB0", "loop://")."""
        return self._name

    @property
    def closed(self) -> bool:
        return self._closed

    def write(self, data: bytes) -> None:
        """Send every byte of data. Raises LinkClosed if closed, LinkTimeout if the line is stuck."""
        self._check_open()
        if data:
            self._write(bytes(data))

    def read(self, max_bytes: int = 4096, timeout_s: float | None = 0.0) -> bytes:
        """Return the bytes available now, at most max_bytes.

        If none are available, wait up to timeout_s seconds for the first one (None: wait
        without limit; 0: do not wait). Returns b"" when the timeout expires with nothing
        received. Raises LinkClosed if this transport is closed, or the other end has gone
        and everything it sent has been read.
        """
        if type(max_bytes) is not int or max_bytes < 1:
            max_bytes = int(check_number("max_bytes", max_bytes, 1, None, integer=True))
        timeout_s = check_timeout("timeout_s", timeout_s)
        self._check_open()
        return self._read(min(max_bytes, MAX_READ_BYTES), timeout_s)

    def close(self) -> None:
        """Release the port; safe to call more than once."""
        if not self._closed:
            self._closed = True
            self._close()
            log.debug("closed %s", self._name)

    def __enter__(self) -> Transport:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __str__(self) -> str:
        return self._name

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return f"<{type(self).__name__} {self._name} {state}>"

    def _check_open(self) -> None:
        if self._closed:
            raise LinkClosed(f"{self._name} is closed")

    @abc.abstractmethod
    def _write(self, data: bytes) -> None: ...

    @abc.abstractmethod
    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes: ...

    @abc.abstractmethod
    def _close(self) -> None: ...


# ------------------------------------------------------------------ in-process transports


class _ByteQueue:
    """A thread-safe byte buffer of at most `capacity` bytes that one side writes and the other reads.

    Once shut, writes are refused and reads drain what is left, then report the end.
    """

    def __init__(self, capacity: int = QUEUE_CAPACITY_BYTES) -> None:
        self._buf = bytearray()
        self._cond = threading.Condition()
        self.capacity = capacity
        self.shut = False

    def __len__(self) -> int:
        return len(self._buf)

    def put(self, data: bytes, timeout_s: float | None) -> int | None:
        """Append data, waiting up to timeout_s (None: without limit) for the reader to make room.
        Returns the bytes left unwritten (0: all of it) or None if the queue is shut. A write
        that fits the capacity goes in whole, never interleaved with another writer's."""
        view = memoryview(data)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._cond:
            while view:
                need = min(len(view), self.capacity)
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                if not self._cond.wait_for(lambda: self.shut or self.capacity - len(self._buf) >= need, left):
                    return len(view)
                if self.shut:
                    return None
                self._buf += view[:need]
                view = view[need:]
                self._cond.notify_all()
            return 0

    def take(self, max_bytes: int, timeout_s: float | None, is_closed) -> bytes | None:
        """Up to max_bytes, waiting at most timeout_s for the first byte.

        Returns b"" on timeout and None when the queue is shut and empty, or when
        is_closed() turns true while waiting (the reader's own end was closed).
        """
        with self._cond:
            self._cond.wait_for(lambda: self._buf or self.shut or is_closed(), timeout_s)
            if is_closed():
                return None
            if self._buf:
                out = bytes(self._buf[:max_bytes])
                del self._buf[:max_bytes]
                self._cond.notify_all()  # a writer may be waiting for room
                return out
            return None if self.shut else b""

    def shut_down(self) -> None:
        with self._cond:
            self.shut = True
            self._cond.notify_all()


class _QueueTransport(Transport):
    """Reads from one _ByteQueue and writes to another (the same one for a loopback).

    A write waits up to write_timeout_s for the reader to make room in a full queue, then
    raises LinkTimeout (as a pty does when nobody reads its other end).
    """

    def __init__(self, name: str, rx: _ByteQueue, tx: _ByteQueue, write_timeout_s: float = 1.0) -> None:
        super().__init__(name)
        self._rx, self._tx = rx, tx
        self._write_timeout_s = check_timeout("write_timeout_s", write_timeout_s)

    @property
    def buffered(self) -> int:
        """Bytes waiting to be read at this end."""
        return len(self._rx)

    def _write(self, data: bytes) -> None:
        left = self._tx.put(data, self._write_timeout_s)
        if left is None:
            raise LinkClosed(f"{self.name}: the other end is closed")
        if left:
            raise LinkTimeout(
                f"{self.name}: nobody is reading the other end; {left} bytes not written after "
                f"{self._write_timeout_s:g} s ({self._tx.capacity} bytes are buffered)"
            )

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        data = self._rx.take(max_bytes, timeout_s, lambda: self._closed)
        if data is None:
            if self._closed:
                raise LinkClosed(f"{self.name} was closed while reading")
            raise LinkClosed(f"{self.name}: the other end is closed")
        return data

    def _close(self) -> None:
        self._rx.shut_down()
        self._tx.shut_down()


class LoopbackTransport(_QueueTransport):
    """What is written is read back, in order. Thread-safe; for tests. Holds at most
    capacity_bytes unread (then a write waits write_timeout_s for a reader, then LinkTimeout)."""

    def __init__(self, capacity_bytes: int = QUEUE_CAPACITY_BYTES, write_timeout_s: float = 1.0) -> None:
        queue = _ByteQueue(_check_capacity(capacity_bytes))
        super().__init__("loop://", queue, queue, write_timeout_s)


class PipeTransport(_QueueTransport):
    """One end of an in-process, thread-safe byte pipe. Make both ends with PipeTransport.pair().

    Each direction holds at most capacity_bytes unread: a write into a full pipe waits up to
    write_timeout_s for the reader, then raises LinkTimeout. Closing either end makes the other
    end's writes raise LinkClosed and its reads raise LinkClosed once the remaining bytes are read.
    """

    @classmethod
    def pair(
        cls, name: str = "pipe", capacity_bytes: int = QUEUE_CAPACITY_BYTES, write_timeout_s: float = 1.0
    ) -> tuple[PipeTransport, PipeTransport]:
        """Two connected ends: bytes written to a are read from b, and the other way round."""
        capacity_bytes = _check_capacity(capacity_bytes)
        a_to_b, b_to_a = _ByteQueue(capacity_bytes), _ByteQueue(capacity_bytes)
        return (cls(f"{name}:a", b_to_a, a_to_b, write_timeout_s), cls(f"{name}:b", a_to_b, b_to_a, write_timeout_s))


def _check_capacity(capacity_bytes: int) -> int:
    return int(check_number("capacity_bytes", capacity_bytes, 1, 1 << 30, integer=True))


# ------------------------------------------------------------------ pseudo-terminal


class PtyTransport(Transport):
    """The master side of a pseudo-terminal pair in raw mode (POSIX only).

    .peer_name is the slave device (e.g. /dev/pts/5): open it with SerialTransport, or hand it
    to another program, to get the other end of a real serial-port path. This object keeps the
    slave open itself, so the pty survives the peer closing and reopening it; bytes written
    before a SerialTransport opens the peer are discarded by pyserial's input flush on open.
    Closing it makes the peer's reads fail as an unplugged device's do. close() from another
    thread wakes a read or write blocked here.
    """

    def __init__(self, write_timeout_s: float = 1.0) -> None:
        write_timeout_s = check_number("write_timeout_s (seconds)", write_timeout_s, 0.0, MAX_TIMEOUT_S)
        try:
            import termios
            import tty
        except ImportError as exc:  # Windows
            raise PortError("pty:// needs a POSIX system with pseudo-terminals") from exc
        master, slave = os.openpty()
        wake_r, wake_w = os.pipe()
        try:
            tty.setraw(slave, termios.TCSANOW)
            os.set_blocking(master, False)
            peer_name = os.ttyname(slave)
        except OSError:
            for fd in (master, slave, wake_r, wake_w):
                os.close(fd)
            raise
        self._master, self._slave = master, slave
        # close() writes to this pipe to wake a thread blocked in select(); the descriptors
        # are released only when no call is using them, so a number is never reused under one
        self._wake_r, self._wake_w = wake_r, wake_w
        self._busy = 0
        self._busy_lock = threading.Lock()
        self._released = False
        self._write_timeout_s = write_timeout_s
        self.peer_name = peer_name
        super().__init__(f"pty:// (peer {peer_name})")

    def _write(self, data: bytes) -> None:
        self._enter()
        try:
            view = memoryview(data)
            deadline = time.monotonic() + self._write_timeout_s
            while view:
                try:
                    view = view[os.write(self._master, view) :]
                    continue
                except BlockingIOError:
                    pass
                except OSError as exc:
                    raise LinkClosed(f"{self.name}: write failed: {exc}") from exc
                left = deadline - time.monotonic()
                if left <= 0:
                    raise LinkTimeout(
                        f"{self.name}: nobody is reading the other end; "
                        f"{len(view)} bytes not written after {self._write_timeout_s} s"
                    )
                select.select([self._wake_r], [self._master], [], left)
                if self._closed:
                    raise LinkClosed(f"{self.name} was closed while writing")
        finally:
            self._leave()

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        self._enter()
        try:
            ready, _, _ = select.select([self._master, self._wake_r], [], [], timeout_s)
            if self._closed:
                raise LinkClosed(f"{self.name} was closed while reading")
            if not ready:
                return b""
            return os.read(self._master, max_bytes)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open anywhere; cannot happen while we hold it
                return b""
            raise LinkClosed(f"{self.name}: read failed: {exc}") from exc
        finally:
            self._leave()

    def _enter(self) -> None:
        with self._busy_lock:
            if self._closed:
                raise LinkClosed(f"{self.name} is closed")
            self._busy += 1

    def _leave(self) -> None:
        with self._busy_lock:
            self._busy -= 1
            if self._closed and self._busy == 0:
                self._release()

    def _close(self) -> None:
        with self._busy_lock:
            if self._released:  # a call that saw `closed` on its way out released already
                return
            if self._busy == 0:
                self._release()
            else:
                os.write(self._wake_w, b"\x00")

    def _release(self) -> None:
        if not self._released:
            self._released = True
            for fd in (self._master, self._slave, self._wake_r, self._wake_w):
                os.close(fd)


# ------------------------------------------------------------------ real serial port


def available_ports() -> list[str]:
    """Device names of the serial ports this machine reports (may be empty)."""
    from serial.tools import list_ports

    try:
        return sorted(p.device for p in list_ports.comports())
    except Exception:  # listing is a courtesy in error messages; never let it mask the real error
        log.debug("could not list serial ports", exc_info=True)
        return []


def _describe_ports() -> str:
    ports = available_ports()
    if not ports:
        return "No serial ports were found on this machine: is the radio plugged in?"
    return "Serial ports on this machine: " + ", ".join(ports)


class SerialTransport(Transport):
    """A serial port through pyserial: 8 data bits, no parity, 1 stop bit.

    baud defaults to the radio's 57,600. The port is opened exclusively, so a second program
    (or a second SerialTransport) on the same port fails with PortError instead of silently
    stealing bytes. write_timeout_s bounds a write on a stuck line (then LinkTimeout).
    """

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, write_timeout_s: float = 1.0) -> None:
        import serial

        if not isinstance(port, str) or not port.strip():
            raise PortSpecError(f"serial port name must be a non-empty string, got {port!r}")
        _check_characters(port, port)
        if not isinstance(baud, int) or isinstance(baud, bool) or not MIN_BAUD <= baud <= MAX_BAUD:
            raise PortSpecError(f"baud rate must be an integer from {MIN_BAUD} to {MAX_BAUD:,}, got {baud!r}")
        write_timeout_s = check_timeout("write_timeout_s", write_timeout_s)
        super().__init__(port)
        self._read_timeout_s: float | None = 0.0
        try:
            self._serial = serial.Serial(
                port=port,
                baudrate=baud,
                bytesize=serial.EIGHTBITS,
                parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE,
                timeout=self._read_timeout_s,
                write_timeout=write_timeout_s,
                exclusive=True,
            )
        except serial.SerialException as exc:
            self._closed = True
            raise PortError(f"cannot open serial port {port!r}: {_why(exc)}. {_describe_ports()}") from None
        except (ValueError, OverflowError) as exc:  # pyserial rejects a setting, e.g. a baud rate the OS lacks
            self._closed = True
            raise PortError(f"cannot configure serial port {port!r} at {baud} baud: {exc}") from None
        except OSError as exc:  # pyserial wraps most; an ioctl or flock may not be
            self._closed = True
            raise PortError(f"cannot open serial port {port!r}: {_why(exc)}. {_describe_ports()}") from None
        self.baud = baud
        log.debug("opened %s at %d baud", port, baud)

    def _write(self, data: bytes) -> None:
        import serial

        try:
            self._serial.write(data)
        except serial.SerialTimeoutException as exc:
            raise LinkTimeout(f"{self.name}: write timed out ({exc}); is flow control holding the line?") from exc
        except OSError as exc:  # SerialException is one; pyserial's ioctls raise bare OSError
            raise LinkClosed(f"{self.name}: write failed, was the device unplugged? ({exc})") from exc

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        try:
            waiting = self._serial.in_waiting
            if waiting:
                return self._serial.read(min(waiting, max_bytes))
            if timeout_s == 0:
                return b""
            self._set_read_timeout(timeout_s)
            first = self._serial.read(1)
            if not first or max_bytes == 1:
                return first
            waiting = self._serial.in_waiting
            return first + (self._serial.read(min(waiting, max_bytes - 1)) if waiting else b"")
        except OSError as exc:  # SerialException is one; pyserial's ioctls raise bare OSError
            if self._closed:
                raise LinkClosed(f"{self.name} was closed while reading") from exc
            raise LinkClosed(f"{self.name}: read failed, was the device unplugged? ({exc})") from exc

    def _set_read_timeout(self, timeout_s: float | None) -> None:
        # pyserial reconfigures the port on every change, so only change it when needed
        if timeout_s != self._read_timeout_s:
            self._serial.timeout = timeout_s
            self._read_timeout_s = timeout_s

    def _close(self) -> None:
        try:
            self._serial.cancel_read()  # wake a thread blocked in read()
            self._serial.close()
        except Exception:  # closing an unplugged device may fail; it is closed either way
            log.debug("error closing %s", self.name, exc_info=True)


def _why(exc: BaseException) -> str:
    """A short reason for a failed open, with a hint for the common causes."""
    code = getattr(exc, "errno", None)
    if code == errno.ENOENT or "FileNotFoundError" in str(exc):
        return "no such port"
    if code in (errno.ENOTTY, errno.EISDIR) or "Inappropriate ioctl" in str(exc) or "Is a directory" in str(exc):
        return "not a serial port (it exists, but is not a terminal device)"
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "lock" in str(exc).lower():
        return "the port is busy: another program (a serial monitor, another rovernav) has it open"
    if code == errno.EACCES or "PermissionError" in str(exc) or "Access is denied" in str(exc):
        if os.name == "nt":  # Windows reports a port held by another program as access denied
            return "access denied: another program (a serial monitor, another rovernav) probably has it open"
        return "permission denied (on Linux, add yourself to the dialout group and log in again)"
    return str(exc)


# ------------------------------------------------------------------ by name

_SPEC_HELP = f"give loop://, pty:// or a serial port such as /dev/ttyUSB0, /dev/ttyUSB0@{DEFAULT_BAUD} or COM4"


def _check_characters(text: str, spec: str) -> None:
    if len(text) > MAX_SPEC_CHARS:
        raise PortSpecError(
            f"transport spec of {len(text):,} characters ({spec[:40]!r}...): at most {MAX_SPEC_CHARS} are accepted"
        )
    bad = next((c for c in text if ord(c) < 32 or ord(c) == 127), None)
    if bad is not None:
        raise PortSpecError(f"control character {bad!r} in transport spec {spec!r}: {_SPEC_HELP}")


def check_spec(spec: str) -> str:
    """`spec` without surrounding blanks, or PortSpecError (nothing is opened): not a string,
    blank, control characters or too long."""
    if not isinstance(spec, str):
        raise PortSpecError(f"transport spec must be a string, got {spec!r}: {_SPEC_HELP}")
    if not spec.strip():
        raise PortSpecError(f"empty transport spec {spec!r}: {_SPEC_HELP}")
    _check_characters(spec, spec)
    return spec.strip()


def parse_serial_spec(spec: str) -> tuple[str, int]:
    """Split "PORT" or "PORT@BAUD" into (port, baud); PortSpecError (a ValueError) naming a bad spec."""
    spec = check_spec(spec)
    if "://" in spec:
        raise PortSpecError(
            f"{spec!r} is not a serial port: give one such as /dev/ttyUSB0, /dev/ttyUSB0@{DEFAULT_BAUD} or COM4"
        )
    port, sep, baud_text = spec.rpartition("@")
    if not sep:
        return spec, DEFAULT_BAUD
    if not port.strip():
        raise PortSpecError(f"no port name before '@' in transport spec {spec!r}: {_SPEC_HELP}")
    if not (baud_text.isascii() and baud_text.isdigit()) or len(baud_text) > 9:
        raise PortSpecError(
            f"bad baud rate {baud_text!r} in transport spec {spec!r}: "
            f"want PORT@BAUD with BAUD an integer from {MIN_BAUD} to {MAX_BAUD:,}"
        )
    baud = int(baud_text, 10)
    if not MIN_BAUD <= baud <= MAX_BAUD:
        raise PortSpecError(
            f"bad baud rate {baud_text!r} in transport spec {spec!r}: must be from {MIN_BAUD} "
            f"to {MAX_BAUD:,} (a port whose name has '@' in it needs its baud added: NAME@{DEFAULT_BAUD})"
        )
    return port, baud


def open_transport(spec: str) -> Transport:
    """Open a transport from a string: "loop://", "pty://", "PORT" or "PORT@BAUD".

    Raises PortSpecError (an InputError, also a ValueError) for a malformed spec, before
    anything is opened, and PortError for a port that cannot be opened, both naming the value
    at fault.
    """
    spec = check_spec(spec)
    if "://" in spec:
        if spec == "loop://":
            return LoopbackTransport()
        if spec == "pty://":
            return PtyTransport()
        raise PortSpecError(f"unknown transport {spec!r}: {_SPEC_HELP}")
    port, baud = parse_serial_spec(spec)
    return SerialTransport(port, baud)
