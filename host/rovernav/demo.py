"""`rovernav demo`: the Uno firmware, booted in simavr, talking to the host over a pty.

Builds the image with Debian's avr-gcc (tools/build_uno.py) and the simavr bridge
(tools/avrsim), starts the bridge with the rover's serial port on a pseudo-terminal, and runs
the same HELLO / listen / counters session as `rovernav link-check` against it. It needs a
checkout of the repository (the firmware sources and tools are not part of the Python package).

What it needs is checked first, and each lack is one line (exit 2) saying what to install:
the checkout, the AVR toolchain (tools/build_uno.py --check-tools), make, and simavr (the
bridge's build or start). A failed build says its last line; `rovernav -v demo` logs the rest.
"""

from __future__ import annotations

import logging
import select
import shutil
import subprocess
import sys
from pathlib import Path

from .errors import SetupError
from .validate import check_number
from .vehicle_gen import LINK_BAUD

log = logging.getLogger("rovernav.demo")

ROOT = Path(__file__).resolve().parents[2]
#: Longest a build step may take [s], and how long the simulator has to say where its pty is.
BUILD_TIMEOUT_S = 900.0
START_TIMEOUT_S = 20.0
#: The header of Debian's libsimavr-dev, which the bridge is built against.
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")


class DemoError(SetupError):
    """The demo could not be set up (no checkout, a build failed, the simulator did not start)."""


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else "no output"


def _run(cmd: list[str], what: str, timeout_s: float = BUILD_TIMEOUT_S) -> subprocess.CompletedProcess:
    try:
        result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, errors="replace", timeout=timeout_s)
    except FileNotFoundError:
        raise DemoError(f"{what}: {cmd[0]} is not installed (on Debian: sudo apt-get install {cmd[0]})") from None
    except subprocess.TimeoutExpired:
        raise DemoError(f"{what} did not finish within {timeout_s:g} s") from None
    except OSError as exc:
        raise DemoError(f"{what}: cannot run {cmd[0]}: {exc.strerror or exc}") from None
    if result.returncode != 0:
        output = (result.stdout + result.stderr).strip()
        for line in output.splitlines()[-30:]:
            log.info("%s: %s", what, line)
        hint = ""
        if "simavr" in output or "sim_avr" in output:
            hint = " (the bridge needs simavr: sudo apt-get install libsimavr-dev)"
        raise DemoError(f"{what} failed{hint}: {_last_line(output)} (rovernav -v demo shows more)")
    return result


def check_tools() -> None:
    """DemoError, one line naming what to install, when the demo cannot be built here."""
    if not (ROOT / "tools" / "build_uno.py").is_file():
        raise DemoError(f"the demo needs a checkout of rovernav (no tools/build_uno.py under {ROOT})")
    try:
        check = subprocess.run(
            [sys.executable, "tools/build_uno.py", "--check-tools"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            errors="replace",
            timeout=60,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise DemoError(f"cannot check the AVR toolchain (tools/build_uno.py --check-tools): {exc}") from None
    if check.returncode != 0:
        lines = [line.strip() for line in check.stdout.splitlines() if line.strip()]
        missing = "; ".join(line for line in lines if line.startswith("missing ")) or _last_line(
            check.stdout + check.stderr
        )
        install = next((line for line in lines if line.startswith("install with")), "")
        raise DemoError(
            f"the demo needs the AVR toolchain, and it is incomplete: {missing}{'; ' + install if install else ''}"
        )
    if shutil.which("make") is None:
        raise DemoError(
            "the demo builds the simavr bridge with make, which is not installed (sudo apt-get install make)"
        )
    bridge = ROOT / "build" / "avrsim" / "rovernav_avrsim"
    if not SIMAVR_HEADER.is_file() and not bridge.is_file():
        raise DemoError(
            f"the demo needs simavr, and it is not installed (no {SIMAVR_HEADER}): "
            "sudo apt-get install simavr libsimavr-dev"
        )


def start_avrsim(elf: Path, speed: float = 1.0, seconds: float | None = None) -> tuple[subprocess.Popen, str]:
    """Start the bridge on elf; return the process and the pty path of the rover's serial port."""
    cmd = [str(ROOT / "build" / "avrsim" / "rovernav_avrsim"), "--pty", "--speed", str(speed)]
    if seconds is not None:
        cmd += ["--seconds", str(seconds)]
    try:
        proc = subprocess.Popen(
            cmd + [str(elf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace"
        )
    except OSError as exc:
        raise DemoError(f"cannot start the AVR simulator {cmd[0]}: {exc.strerror or exc}") from None
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], START_TIMEOUT_S)
    line = proc.stdout.readline(4096).strip() if ready else ""
    if not line.startswith("pty: "):
        proc.kill()
        try:
            _, err = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            err = ""
        if line:
            why = line
        elif (err or "").strip():
            why = _last_line(err)
        else:
            why = f"it said nothing within {START_TIMEOUT_S:g} s"
        if "libsimavr" in why:
            why += " (sudo apt-get install libsimavr-dev)"
        raise DemoError(f"the AVR simulator did not start: {why}")
    return proc, line.split(": ", 1)[1]


def run_demo(seconds: float = 3.0) -> int:
    from .link.check import talk_to_rover
    from .link.link import Link
    from .link.transport import SerialTransport

    seconds = check_number("seconds", seconds, 0.0, 3600.0)
    check_tools()
    print("building the Uno image with Debian's avr-gcc and the simavr bridge ...")
    built = _run([sys.executable, "tools/build_uno.py"], "building the Uno image (tools/build_uno.py)")
    for line in built.stdout.splitlines():
        if line.startswith("flash "):
            print(f"  Uno image: {line.strip()}")
    _run(["make", "-s", "-C", "tools/avrsim"], "building the simavr bridge (make -C tools/avrsim)")
    elf = ROOT / "build" / "uno" / "firmware.elf"
    proc, pty = start_avrsim(elf, speed=1.0)
    print(f"booted build/uno/firmware.elf in simavr (ATmega328P, 16 MHz); its serial port is {pty}")
    try:
        with SerialTransport(pty, LINK_BAUD) as transport:
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
