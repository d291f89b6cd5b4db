"""The compiled Uno image, run in simavr, says HELLO on its serial port and answers ours.

Builds the firmware (tools/build_uno.py) and the UART bridge (tools/avrsim), starts the bridge
on a pseudo-terminal as fast as it can run, and talks to the firmware through the pty with
the host's own frame decoder. Skipped when the AVR toolchain or simavr's headers are missing.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "host"))

from rovernav.link import framing  # noqa: E402
from rovernav.link.messages_gen import SCHEMA_HASH, Hello, Role  # noqa: E402

BRIDGE = ROOT / "build" / "avrsim" / "rovernav_avrsim"
ELF = ROOT / "build" / "uno" / "firmware.elf"
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")

#: Simulated seconds the bridge runs before it stops by itself: the boot HELLO and the answer
#: to ours must both arrive within them.
SIM_SECONDS = 6
#: Wall-clock guard, in case the simulation is far slower than expected.
WALL_TIMEOUT = 15.0


def _missing_tools() -> list[str]:
    missing = []
    if not SIMAVR_HEADER.is_file():
        missing.append("simavr headers (apt-get install libsimavr-dev)")
    for tool, package in (("avr-gcc", "gcc-avr"), ("gcc", "gcc"), ("make", "make")):
        if shutil.which(tool) is None:
            missing.append(f"{tool} ({package})")
    return missing


def _run(cmd: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)


def build_bridge_and_image() -> tuple[Path, Path]:
    """(bridge, firmware ELF), both freshly built (conftest.py's `built` fixture); skips the test
    when the AVR tools are missing."""
    missing = _missing_tools()
    if missing:
        pytest.skip("AVR simulation needs: " + ", ".join(missing))
    firmware = _run([sys.executable, "tools/build_uno.py"])
    if firmware.returncode == 2:
        pytest.skip("the AVR toolchain or Arduino core is incomplete:\n" + firmware.stderr)
    # 1 is also "over budget", which still leaves a runnable image; a compile error does not
    assert ELF.is_file() and (firmware.returncode == 0 or "OVER BUDGET" in firmware.stderr), (
        f"firmware build failed:\n{firmware.stdout}\n{firmware.stderr}"
    )
    bridge = _run(["make", "-C", "tools/avrsim"])
    assert bridge.returncode == 0, f"bridge build failed:\n{bridge.stdout}\n{bridge.stderr}"
    assert BRIDGE.is_file()
    return BRIDGE, ELF


class Bridge:
    """A running rovernav_avrsim; its stderr goes to a file so it can never block on it."""

    def __init__(self, args: list[str], log: Path, **popen) -> None:
        self.log = log
        self._log_file = log.open("wb")
        self.proc = subprocess.Popen(args, stderr=self._log_file, **popen)

    def stderr(self) -> str:
        if not self._log_file.closed:
            self._log_file.flush()
        return self.log.read_text(errors="replace")

    def stop(self) -> int | None:
        """SIGTERM, then SIGKILL if it lingers; the exit status (None if it had to be killed)."""
        code = self.proc.poll()
        if code is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                code = self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                code = None
        for stream in (self.proc.stdin, self.proc.stdout):
            if stream is not None:
                stream.close()
        self._log_file.close()
        return code


@contextlib.contextmanager
def uno_on_a_pty(built: tuple[Path, Path], log: Path, seconds: int):
    """The Uno image in simavr behind a pseudo-terminal for `seconds`: yields the port's path."""
    bridge_bin, elf = built
    bridge = Bridge(
        [str(bridge_bin), "--pty", "--speed", "1", "--seconds", str(seconds), str(elf)], log, stdout=subprocess.PIPE
    )
    try:
        yield _read_line(bridge.proc.stdout, 5.0).decode().strip()[len("pty: ") :]
    finally:
        bridge.stop()


def still_video(path: Path, rover: tuple[float, float, float], target: tuple[float, float], frames: int) -> Path:
    """A video file of one rendered scene, `frames` frames at 30 per second: a camera for a rover
    that does not move (the Uno image in simavr has no plant)."""
    import cv2
    import numpy as np

    from rovernav.sim.camera import Scene, render_frame

    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (640, 480))
    frame = render_frame(Scene(rover=rover, target=target), np.random.default_rng(1))
    for _ in range(frames):
        out.write(frame)
    out.release()
    return path


def _read_line(stream, timeout: float) -> bytes:
    """One line from a pipe, or what came before the timeout."""
    fd = stream.fileno()
    line = b""
    deadline = time.monotonic() + timeout
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            break
        chunk = os.read(fd, 1)
        if not chunk:
            break
        line += chunk
    return line


class PtyReader:
    """Reads frames from the pty, feeding one FrameDecoder for the whole conversation."""

    def __init__(self, fd: int, bridge: Bridge) -> None:
        self.fd = fd
        self.bridge = bridge
        self.decoder = framing.FrameDecoder()
        self.raw = bytearray()

    def next_hello(self, deadline: float) -> framing.Frame:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(
                    f"no HELLO from the firmware within {WALL_TIMEOUT} s wall time; "
                    f"got {bytes(self.raw).hex()}\nbridge stderr:\n{self.bridge.stderr()}"
                )
            if not select.select([self.fd], [], [], min(left, 0.2))[0]:
                if self.bridge.proc.poll() is not None:
                    raise AssertionError(
                        f"the bridge stopped (after {SIM_SECONDS} simulated s at most) before "
                        f"a HELLO arrived; got {bytes(self.raw).hex()}\n"
                        f"bridge stderr:\n{self.bridge.stderr()}"
                    )
                continue
            try:
                data = os.read(self.fd, 4096)
            except OSError as exc:  # EIO: the bridge closed the pty
                if exc.errno != errno.EIO:
                    raise
                data = b""
            if not data:
                raise AssertionError(f"the pty closed before a HELLO arrived\nbridge stderr:\n{self.bridge.stderr()}")
            self.raw += data
            for frame in self.decoder.feed(data):
                if isinstance(frame.message, Hello):
                    return frame


def _assert_rover_hello(frame: framing.Frame) -> None:
    hello = frame.message
    assert hello.role == Role.ROVER
    assert hello.schema_hash == SCHEMA_HASH, f"firmware schema {hello.schema_hash:#010x}, host {SCHEMA_HASH:#010x}"


def _host_hello(seq: int) -> bytes:
    from rovernav.link.link import host_hello

    return framing.encode_frame(host_hello(1), seq)


def test_firmware_hello_over_pty(built, tmp_path):
    bridge_bin, elf = built
    bridge = Bridge(
        [str(bridge_bin), "--pty", "--speed", "0", "--seconds", str(SIM_SECONDS), str(elf)],
        tmp_path / "bridge.log",
        stdout=subprocess.PIPE,
    )
    fd = -1
    try:
        first = _read_line(bridge.proc.stdout, 5.0).decode(errors="replace").strip()
        assert first.startswith("pty: /dev/"), f"first line {first!r}\nbridge stderr:\n{bridge.stderr()}"
        # os.open rather than pyserial: pyserial flushes the input queue when it opens a
        # port, and at --speed 0 the boot HELLO may already be waiting there. The bridge has
        # put the pty in raw mode; nothing here may change it with TCSAFLUSH either.
        fd = os.open(first[len("pty: ") :], os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        reader = PtyReader(fd, bridge)
        deadline = time.monotonic() + WALL_TIMEOUT

        boot = reader.next_hello(deadline)
        _assert_rover_hello(boot)

        os.write(fd, _host_hello(seq=7))
        answer = reader.next_hello(deadline)
        _assert_rover_hello(answer)
        assert answer.seq != boot.seq, "the answer should be a new frame, not the boot HELLO"
        assert answer.message.boot_id == boot.message.boot_id, "the firmware reset in between"

        assert reader.decoder.counters.dropped == 0, reader.decoder.counters
    finally:
        if fd >= 0:
            os.close(fd)
        code = bridge.stop()
    log = bridge.stderr()
    assert code == 0, f"bridge exit status {code}\n{log}"
    assert "simulated" in log and "cycles" in log, log


def test_stdio_answers_every_hello_without_loss(built, tmp_path):
    """Ten HELLOs back to back through stdin: flow control and pacing lose none of them."""
    bridge_bin, elf = built
    sent = b"".join(_host_hello(seq) for seq in range(10))
    result = subprocess.run(
        [str(bridge_bin), "--stdio", "--speed", "0", "--seconds", "1", str(elf)],
        input=sent,
        capture_output=True,
        timeout=WALL_TIMEOUT,
    )
    log = result.stderr.decode(errors="replace")
    assert result.returncode == 0, log
    decoder = framing.FrameDecoder()
    hellos = [f for f in decoder.feed(result.stdout) if isinstance(f.message, Hello)]
    assert decoder.counters.dropped == 0, decoder.counters
    for frame in hellos:
        _assert_rover_hello(frame)
    assert len(hellos) == 1 + len(sent) // len(_host_hello(0)), log  # boot + one per ours
    assert f"{len(sent)} bytes in" in log, log
