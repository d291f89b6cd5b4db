"""`rovernav demo`: the Uno firmware, booted in simavr, talking to the host over a pty.

Builds the image with Debian's avr-gcc (tools/build_uno.py) and the simavr bridge
(tools/avrsim), starts the bridge with the rover's serial port on a pseudo-terminal, and runs
the same HELLO / listen / counters session as `rovernav link-check` against it. It needs a
checkout of the repository (the firmware sources and tools are not part of the Python package).
"""
from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

from .link.errors import LinkError

log = logging.getLogger("rovernav.demo")

ROOT = Path(__file__).resolve().parents[2]


class DemoError(LinkError):
    """The demo could not be set up (no checkout, a build failed, the simulator did not start)."""


def _run(cmd: list[str], what: str) -> None:
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        tail = "\n".join((result.stdout + result.stderr).strip().splitlines()[-15:])
        raise DemoError(f"{what} failed:\n{tail}")
    for line in result.stdout.splitlines():
        if line.startswith("flash "):
            print(f"  Uno image: {line.strip()}")


def start_avrsim(elf: Path, speed: float = 1.0, seconds: float | None = None) -> tuple[subprocess.Popen, str]:
    """Start the bridge on elf; return the process and the pty path of the rover's serial port."""
    cmd = [str(ROOT / "build" / "avrsim" / "rovernav_avrsim"), "--pty", "--speed", str(speed)]
    if seconds is not None:
        cmd += ["--seconds", str(seconds)]
    proc = subprocess.Popen(cmd + [str(elf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line.startswith("pty: "):
        proc.kill()
        err = proc.stderr.read() if proc.stderr else ""
        raise DemoError(f"the AVR simulator did not start: {line or err.strip()}")
    return proc, line.split(": ", 1)[1]


def run_demo(seconds: float = 3.0) -> int:
    from .cli import talk_to_rover
    from .link.link import Link
    from .link.transport import SerialTransport

    if not (ROOT / "tools" / "build_uno.py").is_file():
        raise DemoError(f"the demo needs a checkout of rovernav (no tools/build_uno.py under {ROOT})")
    print("building the Uno image with Debian's avr-gcc and the simavr bridge ...")
    _run([sys.executable, "tools/build_uno.py"], "building the Uno image (tools/build_uno.py)")
    _run(["make", "-s", "-C", "tools/avrsim"], "building the simavr bridge (make -C tools/avrsim)")
    elf = ROOT / "build" / "uno" / "firmware.elf"
    proc, pty = start_avrsim(elf, speed=1.0)
    print(f"booted build/uno/firmware.elf in simavr (ATmega328P, 16 MHz); its serial port is {pty}")
    try:
        with SerialTransport(pty, 57600) as transport:
            link = Link(transport)
            talk_to_rover(link, seconds, 5.0, " (no gyro is simulated: the rover must say so, not hang)")
    finally:
        proc.terminate()
        try:
            _, err = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        for line in (err or "").splitlines():
            if "simulated" in line or "speed" in line:
                log.info("avrsim: %s", line)
    return 0
