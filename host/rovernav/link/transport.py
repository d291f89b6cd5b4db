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

from .errors import LinkClosed, LinkTimeout, PortError

log = logging.getLogger("rovernav.link")

#: The radio's line rate (3DR 433 MHz telemetry radio) and the Uno's serial speed.
DEFAULT_BAUD = 57600


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
        if max_bytes < 1:
            raise ValueError(f"max_bytes must be at least 1, got {max_bytes}")
        if timeout_s is not None and timeout_s < 0:
            raise ValueError(f"timeout_s must be None or >= 0 seconds, got {timeout_s}")
        self._check_open()
        return self._read(max_bytes, timeout_s)

    def close(self) -> None:
        """Release the port; safe to call more than once."""
        if not self._closed:
            self._closed = True
            self._close()
            log.debug("closed %s", self._name)

    def __enter__(self) -> "Transport":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
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
    """A thread-safe, unbounded byte buffer that one side writes and the other reads.

    Once shut, writes are refused and reads drain what is left, then report the end.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._cond = threading.Condition()
        self.shut = False

    def put(self, data: bytes) -> bool:
        """Append data; False (and nothing appended) if the queue is shut."""
        with self._cond:
            if self.shut:
                return False
            self._buf += data
            self._cond.notify_all()
            return True

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
                return out
            return None if self.shut else b""

    def shut_down(self) -> None:
        with self._cond:
            self.shut = True
            self._cond.notify_all()


class _QueueTransport(Transport):
    """Reads from one _ByteQueue and writes to another (the same one for a loopback)."""

    def __init__(self, name: str, rx: _ByteQueue, tx: _ByteQueue) -> None:
        super().__init__(name)
        self._rx, self._tx = rx, tx

    def _write(self, data: bytes) -> None:
        if not self._tx.put(data):
            raise LinkClosed(f"{self.name}: the other end is closed")

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
    """What is written is read back, in order. Thread-safe; for tests."""

    def __init__(self) -> None:
        queue = _ByteQueue()
        super().__init__("loop://", queue, queue)


class PipeTransport(_QueueTransport):
    """One end of an in-process, thread-safe byte pipe. Make both ends with PipeTransport.pair().

    Writes never block (the buffer is unbounded). Closing either end makes the other end's
    writes raise LinkClosed and its reads raise LinkClosed once the remaining bytes are read.
    """

    @classmethod
    def pair(cls, name: str = "pipe") -> tuple["PipeTransport", "PipeTransport"]:
        """Two connected ends: bytes written to a are read from b, and the other way round."""
        a_to_b, b_to_a = _ByteQueue(), _ByteQueue()
        return cls(f"{name}:a", b_to_a, a_to_b), cls(f"{name}:b", a_to_b, b_to_a)


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
                    view = view[os.write(self._master, view):]
                    continue
                except BlockingIOError:
                    pass
                except OSError as exc:
                    raise LinkClosed(f"{self.name}: write failed: {exc}") from exc
                left = deadline - time.monotonic()
                if left <= 0:
                    raise LinkTimeout(f"{self.name}: nobody is reading the other end; "
                                      f"{len(view)} bytes not written after {self._write_timeout_s} s")
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
            raise ValueError(f"serial port name must be a non-empty string, got {port!r}")
        if not isinstance(baud, int) or isinstance(baud, bool) or baud <= 0:
            raise ValueError(f"baud rate must be a positive integer, got {baud!r}")
        super().__init__(port)
        self._read_timeout_s: float | None = 0.0
        try:
            self._serial = serial.Serial(
                port=port, baudrate=baud, bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE, timeout=self._read_timeout_s,
                write_timeout=write_timeout_s, exclusive=True)
        except serial.SerialException as exc:
            self._closed = True
            raise PortError(f"cannot open serial port {port!r}: {_why(exc)}. {_describe_ports()}") from None
        except ValueError as exc:  # pyserial rejects a setting, e.g. a baud rate the OS lacks
            self._closed = True
            raise PortError(f"cannot configure serial port {port!r} at {baud} baud: {exc}") from None
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
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "lock" in str(exc).lower():
        return "the port is busy: another program (a serial monitor, another rovernav) has it open"
    if code == errno.EACCES or "PermissionError" in str(exc) or "Access is denied" in str(exc):
        if os.name == "nt":  # Windows reports a port held by another program as access denied
            return "access denied: another program (a serial monitor, another rovernav) probably has it open"
        return "permission denied (on Linux, add yourself to the dialout group and log in again)"
    return str(exc)


# ------------------------------------------------------------------ by name

def parse_serial_spec(spec: str) -> tuple[str, int]:
    """Split "PORT" or "PORT@BAUD" into (port, baud); ValueError naming a bad spec."""
    port, sep, baud_text = spec.rpartition("@")
    if not sep:
        return spec, DEFAULT_BAUD
    if not port:
        raise ValueError(f"no port name before '@' in transport spec {spec!r}")
    try:
        baud = int(baud_text, 10)
    except ValueError:
        raise ValueError(f"bad baud rate {baud_text!r} in transport spec {spec!r}") from None
    if baud <= 0:
        raise ValueError(f"bad baud rate {baud_text!r} in transport spec {spec!r}: must be positive")
    return port, baud


def open_transport(spec: str) -> Transport:
    """Open a transport from a string: "loop://", "pty://", "PORT" or "PORT@BAUD".

    Raises ValueError for a malformed spec and PortError for a port that cannot be opened,
    both naming the value at fault.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"empty transport spec {spec!r}: give loop://, pty:// or a serial port name")
    spec = spec.strip()
    if "://" in spec:
        if spec == "loop://":
            return LoopbackTransport()
        if spec == "pty://":
            return PtyTransport()
        raise ValueError(f"unknown transport {spec!r}: expected loop://, pty://, "
                         f"or a serial port such as /dev/ttyUSB0@57600 or COM4")
    port, baud = parse_serial_spec(spec)
    return SerialTransport(port, baud)
