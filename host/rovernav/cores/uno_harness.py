"""The simavr harness that runs the Uno image: tools/avrsim/unocore.c, built as
build/avrsim/libunocore.so and loaded with ctypes, and the image it runs (build/uno/firmware.elf).

- `ensure_built()` builds the image (tools/build_uno.py) and the harness (make -C tools/avrsim
  unocore) when they are missing or older than their sources, naming missing Debian packages;
- `load_library()` loads the harness, declares its entry points and checks its ABI version and
  its structs' sizes against their ctypes copies, generated from firmware/abi/abi.toml into
  rovernav.cores.abi_gen (the `_Step`, `_Regs`, `_Stats` the core reads each step, and the
  profile's structs, read by rovernav.cores.profile).

Used by rovernav.cores.uno (`UnoCore`), rovernav.cores.elf and rovernav.cores.profile.
"""

from __future__ import annotations

import ctypes
import logging
import shutil
import subprocess
import sys
from pathlib import Path

from ..vehicle_gen import STEP_PERIOD_MS
from .abi_gen import (
    PROF_KINDS_NAMES,
    UNOCORE_ABI_STRUCTS,
    UNOCORE_ABI_VERSION,
    UnocoreProfEntry,
    UnocoreProfInfo,
    UnocoreProfStep,
    UnocoreRegs,
    UnocoreStats,
    UnocoreStep,
)
from .protocol import FirmwareBuildError

log = logging.getLogger("rovernav.cores.uno")

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware"
ELF = ROOT / "build" / "uno" / "firmware.elf"
LIBRARY = ROOT / "build" / "avrsim" / "libunocore.so"
HARNESS_SRC = ROOT / "tools" / "avrsim" / "unocore.c"
BOARD_H = FIRMWARE / "lib" / "hal" / "board.h"
VEHICLE_H = FIRMWARE / "lib" / "link" / "vehicle_gen.h"  # included by board.h
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")

CLOCK_HZ = 16_000_000
CYCLES_PER_MS = CLOCK_HZ // 1000
ABI_VERSION = UNOCORE_ABI_VERSION
STEP_US = STEP_PERIOD_MS * 1000  # the image's step period (main.cpp's, from vehicle_gen.h)

# Step descriptor (GPIOR0) bits, written by main.cpp at the end of each step.
DESC_STATE_MASK = 0x0F
DESC_FLAGS = {"fix": 0x10, "sonar": 0x20, "replanning": 0x40, "radio_rx": 0x80}


class UnoSetupError(FirmwareBuildError):
    """The image or the harness cannot be built or loaded (a missing Debian package, say)."""


# ---------------------------------------------------------------------------- ctypes layout
# unocore.c's structs, generated from firmware/abi/abi.toml (firmware/abi/generate.py), which also
# writes them for C in tools/avrsim/unocore_abi_gen.h.

# (The short names are the ones uno.py, profile.py and the tests use.)
_Step, _Regs, _Stats = UnocoreStep, UnocoreRegs, UnocoreStats
_ProfInfo, _ProfEntry, _ProfStep = UnocoreProfInfo, UnocoreProfEntry, UnocoreProfStep
PROF_KINDS = PROF_KINDS_NAMES  # unocore.c's order

#: The harness's structs, in unocore_struct_sizes()'s order (checked when the library loads).
HARNESS_STRUCTS = UNOCORE_ABI_STRUCTS

_SONAR_FN = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p)

# ---------------------------------------------------------------------------- building


def missing_packages() -> dict[str, str]:
    """Debian package -> what of it is missing, for the image and the harness."""
    missing: dict[str, str] = {}
    for tool, package in (("avr-gcc", "gcc-avr"), ("avr-objcopy", "binutils-avr"), ("gcc", "gcc"), ("make", "make")):
        if shutil.which(tool) is None:
            missing[package] = tool
    if not Path("/usr/lib/avr/include/avr/io.h").is_file():
        missing["avr-libc"] = "/usr/lib/avr/include/avr/io.h"
    if not SIMAVR_HEADER.is_file():
        missing["libsimavr-dev"] = str(SIMAVR_HEADER)
    return missing


def _newest_mtime(paths) -> float:
    return max((p.stat().st_mtime for p in paths if p.is_file()), default=0.0)


def _firmware_sources() -> list[Path]:
    return [
        p for d in ("src", "lib") for p in (FIRMWARE / d).rglob("*") if p.suffix in (".c", ".cpp", ".h", ".S", ".json")
    ]


def _run(cmd: list[str], what: str) -> None:
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        raise UnoSetupError(f"{what} failed ({' '.join(cmd)}):\n{(result.stdout + result.stderr)[-3000:]}")


def ensure_built(elf: Path = ELF) -> tuple[Path, Path]:
    """Builds the Uno image (tools/build_uno.py) and the harness (make -C tools/avrsim unocore)
    when they are missing or older than their sources; returns (elf, library).

    A stale image whose rebuild fails (somebody's edit in progress) is used as it is, with a
    warning; a missing one is an error. Missing Debian packages are named in the error."""
    from ..files import build_lock

    with build_lock(ROOT / "build"):
        return _ensure_built(elf)


def _ensure_built(elf: Path) -> tuple[Path, Path]:
    missing = missing_packages()
    need_elf = not elf.is_file()
    need_lib = not LIBRARY.is_file()
    if missing and (need_elf or need_lib):
        raise UnoSetupError(
            "`--rover uno` needs these Debian packages: "
            + ", ".join(f"{pkg} ({what})" for pkg, what in sorted(missing.items()))
            + f"; install with: sudo apt-get install {' '.join(sorted(missing))}"
        )
    if elf == ELF and FIRMWARE.is_dir() and (need_elf or _newest_mtime(_firmware_sources()) > elf.stat().st_mtime):
        try:
            _run([sys.executable, str(ROOT / "tools" / "build_uno.py")], "building the Uno image")
        except UnoSetupError:
            if need_elf:
                raise
            log.warning(
                "the Uno image is older than the firmware sources and does not rebuild; running the old %s", elf
            )
    harness = [*HARNESS_SRC.parent.glob("*.[ch]"), HARNESS_SRC.parent / "Makefile"]  # tools/avrsim
    if need_lib or _newest_mtime(harness) > LIBRARY.stat().st_mtime:
        _run(["make", "-s", "-C", str(ROOT / "tools" / "avrsim"), "unocore"], "building the simavr harness")
    return elf, LIBRARY


_lib: ctypes.CDLL | None = None


def load_library() -> ctypes.CDLL:
    global _lib
    if _lib is not None:
        return _lib
    try:
        lib = ctypes.CDLL(str(LIBRARY))
    except OSError as exc:
        raise UnoSetupError(
            f"cannot load {LIBRARY}: {exc} (is libsimavr2 installed? sudo apt-get install libsimavr-dev)"
        ) from exc
    P = ctypes.c_void_p
    lib.unocore_abi_version.restype = ctypes.c_uint32
    lib.unocore_new.restype = P
    lib.unocore_new.argtypes = [
        ctypes.c_char_p,
        ctypes.c_uint16,
        ctypes.c_uint16,
        ctypes.c_uint8,
        ctypes.c_uint8,
        ctypes.c_uint32,
        ctypes.c_char_p,
        ctypes.c_uint32,
    ]
    lib.unocore_free.argtypes = [P]
    lib.unocore_free.restype = None
    lib.unocore_set_sonar.argtypes = [P, _SONAR_FN, P]
    lib.unocore_set_sonar.restype = None
    lib.unocore_set_fast_forward.argtypes = [P, ctypes.c_int]
    lib.unocore_set_fast_forward.restype = None
    lib.unocore_set_gyro.argtypes = [P, ctypes.c_int, ctypes.c_int32]
    lib.unocore_set_gyro.restype = None
    lib.unocore_rx.argtypes = [P, ctypes.c_char_p, ctypes.c_uint32]
    lib.unocore_rx.restype = ctypes.c_uint32
    lib.unocore_tx.argtypes = [P, ctypes.c_char_p, ctypes.c_uint32]
    lib.unocore_tx.restype = ctypes.c_uint32
    lib.unocore_run_to.argtypes = [P, ctypes.c_uint64]
    lib.unocore_run_to.restype = ctypes.c_int
    lib.unocore_reset.argtypes = [P, ctypes.c_uint8]
    lib.unocore_reset.restype = None
    lib.unocore_hold_pin_low.argtypes = [P, ctypes.c_char, ctypes.c_uint8, ctypes.c_int]
    lib.unocore_hold_pin_low.restype = ctypes.c_int
    lib.unocore_regs_read.argtypes = [P, ctypes.POINTER(_Regs)]
    lib.unocore_regs_read.restype = None
    lib.unocore_steps.argtypes = [P, ctypes.POINTER(_Step), ctypes.c_uint32, ctypes.c_int]
    lib.unocore_steps.restype = ctypes.c_uint32
    lib.unocore_stats_read.argtypes = [P, ctypes.POINTER(_Stats)]
    lib.unocore_stats_read.restype = None
    lib.unocore_peek.argtypes = [P, ctypes.c_uint16]
    lib.unocore_peek.restype = ctypes.c_uint8
    lib.unocore_eeprom.argtypes = [P, ctypes.c_uint16, ctypes.c_char_p, ctypes.c_uint16, ctypes.c_int]
    lib.unocore_eeprom.restype = ctypes.c_int
    lib.unocore_pc.argtypes = [P]
    lib.unocore_pc.restype = ctypes.c_uint32
    U64P = ctypes.POINTER(ctypes.c_uint64)
    lib.unocore_profile_start.argtypes = [
        P,
        ctypes.POINTER(ctypes.c_uint16),
        ctypes.c_uint32,
        ctypes.POINTER(ctypes.c_uint8),
        ctypes.c_uint32,
        ctypes.c_uint32,
    ]
    lib.unocore_profile_start.restype = ctypes.c_int
    lib.unocore_profile_info.argtypes = [P, ctypes.POINTER(_ProfInfo)]
    lib.unocore_profile_info.restype = None
    lib.unocore_profile_read.argtypes = [P, ctypes.c_uint32, U64P, U64P, U64P, ctypes.c_uint32]
    lib.unocore_profile_read.restype = ctypes.c_uint32
    lib.unocore_profile_worst.argtypes = [
        P,
        ctypes.c_uint32,
        ctypes.POINTER(_ProfStep),
        ctypes.POINTER(_ProfEntry),
        ctypes.c_uint32,
    ]
    lib.unocore_profile_worst.restype = ctypes.c_uint32
    if lib.unocore_abi_version() != ABI_VERSION:
        raise UnoSetupError(
            f"{LIBRARY} has ABI version {lib.unocore_abi_version()}, expected {ABI_VERSION}: "
            "rebuild it (make -C tools/avrsim unocore)"
        )
    lib.unocore_struct_sizes.restype = ctypes.c_uint32
    lib.unocore_struct_sizes.argtypes = [ctypes.POINTER(ctypes.c_uint32), ctypes.c_uint32]
    sizes = (ctypes.c_uint32 * 16)()
    count = lib.unocore_struct_sizes(sizes, 16)
    for st, size in zip(HARNESS_STRUCTS, sizes[:count]):
        if ctypes.sizeof(st) != size:
            raise UnoSetupError(
                f"tools/avrsim/unocore.c and host/rovernav/cores/abi_gen.py disagree: "
                f"{st._c_name_} is {size} bytes there, {ctypes.sizeof(st)} here"
            )
    if count != len(HARNESS_STRUCTS):
        raise UnoSetupError(f"unocore.c names {count} structs, cores/abi_gen.py {len(HARNESS_STRUCTS)}")
    _lib = lib
    return lib
