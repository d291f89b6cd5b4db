"""The Uno image itself as the simulated rover's firmware: `rovernav sim --rover uno`.

`UnoCore` runs build/uno/firmware.elf in simavr (tools/avrsim/unocore.c, loaded from
build/avrsim/libunocore.so with ctypes) with the simulated world on its pins, and is a
`rovernav.cores.protocol.RoverCore` like `rovernav.cores.native.NativeCore`, so the simulator's
loop (sim/runner.py) steps either one:

- `step(now_ms, gyro_rate_mdps=..., rx=...)` hands the MPU-6050 model the yaw rate and the
  UART the radio's bytes (paced at 57,600 baud), runs the AVR up to cycle now * 16 MHz, and
  reads back what its pins say: the motor PWM (Timer0/Timer2 compare registers and the port
  bits when analogWrite has disconnected them), the servo angle (Timer1's pulse width, turned
  into an angle with board.h's constants), whether TRIG rose (`fire_sonar`), and the bytes
  the UART sent. `sonar_range_mm` and `tx_room` are ignored: the image pings the HC-SR04
  model itself (the range comes from the `sonar` callback at the TRIG edge), and its own TX
  buffer limits what it sends.
- `probe()` is what the report and the pictures need: the state from the step descriptor the
  image writes to GPIOR0 (when it has the hook) or from its last STATUS, the pose and its
  uncertainty from its last STATUS. Never fed back to the rover.
- `timing()` is the report's "uno_timing": step times per state and per flag from PB0's edges
  and the GPIOR0 descriptors, the worst step, the period's jitter, the stack's high-water
  mark, and counters (gyro transactions, pings, UART bytes, how fast the AVR ran).
- `enable_profile()` (or `UnoCore(profile=True)`, `rovernav sim --rover uno --profile`) adds
  uno_timing["profile"]: where the steps' cycles go, by function of the ELF's symbol table
  (`function_map`), for all steps, the steps with a FIX, with sonar, ..., and the worst 1 %.
  The harness counts every instruction executed while PB0 is high (see unocore.c, "Profile").

Time: the AVR's cycle 0 is the simulated time the core was made at; step(now_ms) runs it to
(now_ms - start_ms) * 16,000 cycles, so its outputs at `now` are what its pins showed at `now`,
and the plant moves under them for the next 10 ms, as with the native core.
"""
from __future__ import annotations

import ctypes
import dataclasses
import logging
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

from .protocol import FirmwareBuildError, Probe, StepOut
from ..link import messages_gen as mg
from ..link.framing import FrameDecoder, Verifier, crc16
from ..link.messages_gen import SIGN_ROVER_TO_HOST

log = logging.getLogger("rovernav.cores.uno")

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware"
ELF = ROOT / "build" / "uno" / "firmware.elf"
LIBRARY = ROOT / "build" / "avrsim" / "libunocore.so"
HARNESS_SRC = ROOT / "tools" / "avrsim" / "unocore.c"
BOARD_H = FIRMWARE / "lib" / "hal" / "board.h"
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")

CLOCK_HZ = 16_000_000
CYCLES_PER_MS = CLOCK_HZ // 1000
ABI_VERSION = 3
STEP_US = 10_000               # the image's step period (main.cpp kStepMs)

# Step descriptor (GPIOR0) bits, written by main.cpp at the end of each step.
DESC_STATE_MASK = 0x0F
DESC_FLAGS = {"fix": 0x10, "sonar": 0x20, "replanning": 0x40, "radio_rx": 0x80}


class UnoSetupError(FirmwareBuildError):
    """The image or the harness cannot be built or loaded (a missing Debian package, say)."""


class UnoCrashError(RuntimeError):
    """simavr stopped the AVR core (an illegal instruction, a jump out of the flash)."""


# ---------------------------------------------------------------------------- ctypes layout

class _Step(ctypes.Structure):
    _fields_ = [("rise", ctypes.c_uint64), ("fall", ctypes.c_uint64), ("desc", ctypes.c_uint8),
                ("has_desc", ctypes.c_uint8), ("pad", ctypes.c_uint8 * 2), ("boot", ctypes.c_uint32)]


class _Regs(ctypes.Structure):
    _fields_ = [("tccr0a", ctypes.c_uint8), ("ocr0a", ctypes.c_uint8), ("ocr0b", ctypes.c_uint8),
                ("tccr2a", ctypes.c_uint8), ("ocr2a", ctypes.c_uint8), ("ocr2b", ctypes.c_uint8),
                ("portb", ctypes.c_uint8), ("ddrb", ctypes.c_uint8), ("portd", ctypes.c_uint8),
                ("ddrd", ctypes.c_uint8), ("tccr1a", ctypes.c_uint8), ("tccr1b", ctypes.c_uint8),
                ("icr1", ctypes.c_uint16), ("ocr1a", ctypes.c_uint16),
                ("last_desc", ctypes.c_uint8), ("has_desc", ctypes.c_uint8),
                ("pings", ctypes.c_uint32), ("echoes", ctypes.c_uint32), ("steps", ctypes.c_uint32)]


class _Stats(ctypes.Structure):
    _fields_ = [("cycle", ctypes.c_uint64), ("skipped_cycles", ctypes.c_uint64), ("skips", ctypes.c_uint64),
                ("resets", ctypes.c_uint32), ("cpu_state", ctypes.c_int32), ("crash_pc", ctypes.c_uint32),
                ("uart_bytes_in", ctypes.c_uint32), ("uart_bytes_out", ctypes.c_uint32),
                ("uart_xoffs", ctypes.c_uint32), ("uart_rx_queued", ctypes.c_uint32),
                ("twi_addressed", ctypes.c_uint32), ("twi_nacked", ctypes.c_uint32),
                ("twi_bytes_written", ctypes.c_uint32), ("twi_bytes_read", ctypes.c_uint32),
                ("twi_whoami_reads", ctypes.c_uint32), ("twi_gyro_reads", ctypes.c_uint32),
                ("twi_status_fixed", ctypes.c_uint32), ("twi_twint_cleared", ctypes.c_uint32),
                ("twi_twsto_cleared", ctypes.c_uint32),
                ("pings", ctypes.c_uint32), ("echoes", ctypes.c_uint32), ("pings_ignored", ctypes.c_uint32),
                ("paint_start", ctypes.c_uint16), ("ramend", ctypes.c_uint16),
                ("stack_lowest", ctypes.c_uint16), ("pad", ctypes.c_uint16),
                ("sim_warnings", ctypes.c_uint32), ("timer_modes_filled", ctypes.c_uint32)]


PROF_KINDS = ("all", "fix", "sonar", "replanning", "radio_rx", "no_flags")   # unocore.c's order
PROF_CTX = 64


class _ProfInfo(ctypes.Structure):
    _fields_ = [("nfuncs", ctypes.c_uint32), ("nctx", ctypes.c_uint32), ("nkeys", ctypes.c_uint32),
                ("nkinds", ctypes.c_uint32), ("nedges", ctypes.c_uint32), ("open_frames", ctypes.c_uint32),
                ("steps", ctypes.c_uint64 * len(PROF_KINDS)), ("step_cycles", ctypes.c_uint64 * len(PROF_KINDS)),
                ("attributed", ctypes.c_uint64 * len(PROF_KINDS)), ("instructions", ctypes.c_uint64),
                ("worst_kept", ctypes.c_uint32), ("worst_cap", ctypes.c_uint32),
                ("unfinished", ctypes.c_uint32), ("depth_lost", ctypes.c_uint32)]


class _ProfEntry(ctypes.Structure):
    _fields_ = [("key", ctypes.c_uint32), ("cycles", ctypes.c_uint32), ("calls", ctypes.c_uint32),
                ("incl", ctypes.c_uint32)]


class _ProfStep(ctypes.Structure):
    _fields_ = [("rise", ctypes.c_uint64), ("fall", ctypes.c_uint64), ("desc", ctypes.c_uint8),
                ("has_desc", ctypes.c_uint8), ("pad", ctypes.c_uint8 * 2), ("n", ctypes.c_uint32)]


#: The harness's structs, in unocore_struct_sizes()'s order (checked when the library loads).
HARNESS_STRUCTS = (_Step, _Regs, _Stats, _ProfInfo, _ProfEntry, _ProfStep)

_SONAR_FN = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p)


# ---------------------------------------------------------------------------- building

def missing_packages() -> dict[str, str]:
    """Debian package -> what of it is missing, for the image and the harness."""
    missing: dict[str, str] = {}
    for tool, package in (("avr-gcc", "gcc-avr"), ("avr-objcopy", "binutils-avr"), ("gcc", "gcc"),
                          ("make", "make")):
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
    return [p for d in ("src", "lib") for p in (FIRMWARE / d).rglob("*")
            if p.suffix in (".c", ".cpp", ".h", ".S", ".json")]


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
        raise UnoSetupError("`--rover uno` needs these Debian packages: " +
                            ", ".join(f"{pkg} ({what})" for pkg, what in sorted(missing.items())) +
                            f"; install with: sudo apt-get install {' '.join(sorted(missing))}")
    if elf == ELF and FIRMWARE.is_dir() and (need_elf or _newest_mtime(_firmware_sources()) > elf.stat().st_mtime):
        try:
            _run([sys.executable, str(ROOT / "tools" / "build_uno.py")], "building the Uno image")
        except UnoSetupError:
            if need_elf:
                raise
            log.warning("the Uno image is older than the firmware sources and does not rebuild; "
                        "running the old %s", elf)
    if need_lib or HARNESS_SRC.stat().st_mtime > LIBRARY.stat().st_mtime:
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
        raise UnoSetupError(f"cannot load {LIBRARY}: {exc} (is libsimavr2 installed? "
                            "sudo apt-get install libsimavr-dev)") from exc
    P = ctypes.c_void_p
    lib.unocore_abi_version.restype = ctypes.c_uint32
    lib.unocore_new.restype = P
    lib.unocore_new.argtypes = [ctypes.c_char_p, ctypes.c_uint16, ctypes.c_uint16, ctypes.c_uint8,
                                ctypes.c_uint8, ctypes.c_uint32, ctypes.c_char_p, ctypes.c_uint32]
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
    lib.unocore_profile_start.argtypes = [P, ctypes.POINTER(ctypes.c_uint16), ctypes.c_uint32,
                                          ctypes.POINTER(ctypes.c_uint8), ctypes.c_uint32, ctypes.c_uint32]
    lib.unocore_profile_start.restype = ctypes.c_int
    lib.unocore_profile_info.argtypes = [P, ctypes.POINTER(_ProfInfo)]
    lib.unocore_profile_info.restype = None
    lib.unocore_profile_read.argtypes = [P, ctypes.c_uint32, U64P, U64P, U64P, ctypes.c_uint32]
    lib.unocore_profile_read.restype = ctypes.c_uint32
    lib.unocore_profile_worst.argtypes = [P, ctypes.c_uint32, ctypes.POINTER(_ProfStep),
                                          ctypes.POINTER(_ProfEntry), ctypes.c_uint32]
    lib.unocore_profile_worst.restype = ctypes.c_uint32
    if lib.unocore_abi_version() != ABI_VERSION:
        raise UnoSetupError(f"{LIBRARY} has ABI version {lib.unocore_abi_version()}, expected {ABI_VERSION}: "
                            "rebuild it (make -C tools/avrsim unocore)")
    lib.unocore_struct_sizes.restype = ctypes.c_uint32
    lib.unocore_struct_sizes.argtypes = [ctypes.POINTER(ctypes.c_uint32), ctypes.c_uint32]
    sizes = (ctypes.c_uint32 * 16)()
    count = lib.unocore_struct_sizes(sizes, 16)
    for name, st, size in zip(("step", "regs", "stats", "prof_info", "prof_entry", "prof_step"), HARNESS_STRUCTS,
                              sizes[:count]):
        if ctypes.sizeof(st) != size:
            raise UnoSetupError(f"tools/avrsim/unocore.c and host/rovernav/cores/uno.py disagree: unocore_{name} is "
                                f"{size} bytes there, {ctypes.sizeof(st)} here")
    if count != len(HARNESS_STRUCTS):
        raise UnoSetupError(f"unocore.c names {count} structs, cores/uno.py {len(HARNESS_STRUCTS)}")
    _lib = lib
    return lib


# ---------------------------------------------------------------------------- the image

@dataclasses.dataclass(frozen=True)
class Board:
    """The board.h constants the harness needs to read the pins the way the firmware drives them."""

    servo_pulse_min_us: int
    servo_pulse_max_us: int
    servo_centre_trim_cdeg: int
    servo_clockwise_sign: int
    gyro_z_to_clockwise_sign: int
    mpu_address: int
    serial_baud: int
    eeprom_link_addr: int
    pin_consent: int          # held to GND at a reset: the owner's consent to a new link key


def uno_pin_port(pin: int) -> tuple[str, int]:
    """An Arduino Uno pin number's AVR port and bit: D0-D7 on PORTD, D8-D13 on PORTB, A0-A5 (14-19) on PORTC."""
    if 0 <= pin <= 7:
        return "D", pin
    if 8 <= pin <= 13:
        return "B", pin - 8
    if 14 <= pin <= 19:
        return "C", pin - 14
    raise ValueError(f"the Uno has no pin {pin}")


def board_constants(path: Path = BOARD_H) -> Board:
    text = path.read_text(encoding="utf-8")

    def value(name: str) -> int:
        m = re.search(rf"\b{name}\s*=\s*(-?(?:0x[0-9A-Fa-f]+|\d+))", text)
        if m is None:
            raise UnoSetupError(f"{path}: no constant {name}")
        return int(m.group(1), 0)

    return Board(value("kServoPulseMinUs"), value("kServoPulseMaxUs"), value("kServoCentreTrimCdeg"),
                 value("kServoClockwiseSign"), value("kGyroZToClockwiseSign"), value("kMpuAddress"),
                 value("kSerialBaud"), value("kEepromLinkAddr"), value("kPinConsent"))


def link_key_record(key: bytes) -> bytes:
    """The key record firmware/lib/hal/link_store.h keeps in EEPROM: 0xA5, the key, its CRC-16."""
    rec = b"\xA5" + bytes(key)
    return rec + crc16(rec).to_bytes(2, "little")


def _elf_sections(elf: Path) -> tuple[bytes, list[tuple[str, tuple]]]:
    """The ELF's bytes and its section headers as (name, (sh_name, type, flags, addr, offset,
    size, link, info, addralign, entsize))."""
    data = elf.read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise UnoSetupError(f"{elf} is not a 32-bit little-endian ELF (an AVR image?)")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    names_off = sections[shstrndx][4]

    def name(sec) -> str:
        start = names_off + sec[0]
        return data[start:data.index(b"\0", start)].decode("ascii", "replace")

    return data, [(name(sec), sec) for sec in sections]


def static_ram_end(elf: Path) -> int:
    """The first SRAM address above .data, .bss and .noinit (where the heap, and the stack's
    deepest reach, would begin), from the ELF's section headers."""
    _, sections = _elf_sections(elf)
    end = 0x100  # the 328P's SRAM starts at 0x100
    for name, sec in sections:
        addr, size = sec[3], sec[5]
        if name in (".data", ".bss", ".noinit") and 0x800000 <= addr < 0x810000:
            end = max(end, addr - 0x800000 + size)
    return end


# ---------------------------------------------------------------------------- the symbol map

NO_SYMBOL = "(no symbol)"

# ATmega328P interrupt vectors (datasheet table 12-6), by number; 0 is RESET.
VECTORS_328P = ("RESET", "INT0", "INT1", "PCINT0", "PCINT1", "PCINT2", "WDT", "TIMER2_COMPA", "TIMER2_COMPB",
                "TIMER2_OVF", "TIMER1_CAPT", "TIMER1_COMPA", "TIMER1_COMPB", "TIMER1_OVF", "TIMER0_COMPA",
                "TIMER0_COMPB", "TIMER0_OVF", "SPI_STC", "USART_RX", "USART_UDRE", "USART_TX", "ADC", "EE_READY",
                "ANALOG_COMP", "TWI", "SPM_READY")

# avr-libc's float routines (libm, libgcc's soft float on the AVR) and libgcc's integer helpers
FLOAT_LIBRARY = re.compile(
    r"^(__(add|sub|mul|div|neg)sf3\w*|__fp_\w+|__fix(uns)?sfsi|__float(un)?sisf|__(cmp|eq|ne|lt|le|gt|ge|unord)sf2"
    r"|a?sinh?|a?cosh?|a?tanh?|atan2|sqrt|cbrt|hypot|fabs|l?l?round|l?rint|floor|ceil|trunc|fmod|modf|exp|log|log10"
    r"|pow|ldexp|frexp|square|inverse|fmin|fmax|fdim|fma|copysign|signbit|isinf|isnan|isfinite)$")
INTEGER_LIBRARY = re.compile(r"^__(u?(mul|div|mod|divmod)[qhsd]i[34]\w*|u?mulh?isi3|umulhisi3|usmulhisi3|"
                             r"mulshisi3|muluhisi3|mulsidi3|umulsidi3|negsi2|ashl|ashr|lshr|cmpdi2|prologue_saves__|"
                             r"epilogue_restores__|tablejump\w*)")


@dataclasses.dataclass(frozen=True)
class FunctionMap:
    """Which function each flash word of the image belongs to, from its symbol table."""

    names: list[str]           # demangled; the last one is NO_SYMBOL
    raw_names: list[str]       # as in the symbol table (the first of several entry points)
    starts: list[int]          # first byte address (0xFFFFFFFF for NO_SYMBOL)
    func_of_word: list[int]    # index into names, for each flash word of .text
    entry_words: list[int]     # 1 where a function's symbol (or another entry point of it) starts
    vector_handlers: dict[int, str]   # vector number -> the name of the function it jumps to

    @property
    def no_symbol(self) -> int:
        return len(self.names) - 1


def _demangle(names: list[str]) -> list[str]:
    for tool in ("avr-c++filt", "c++filt"):
        path = shutil.which(tool)
        if path is None:
            continue
        try:
            out = subprocess.run([path], input="\n".join(names) + "\n", capture_output=True, text=True,
                                 timeout=30, check=True).stdout.splitlines()
        except (OSError, subprocess.SubprocessError):
            continue
        if len(out) == len(names):
            return out
    return list(names)


def function_map(elf: Path) -> FunctionMap:
    """The functions of .text from the ELF's symbol table.

    - A sized symbol (FUNC or NOTYPE) covers [value, value + size), or up to the next sized
      symbol or hidden global label if that comes first (avr-ld's relaxation shrinks CALLs to
      RCALLs after avr-libc's sizes were taken).
    - An unsized label (the startup code's, __vectors, __bad_interrupt) covers from its address
      to the next symbol. Where several symbols share an address, a sized one wins, then a
      global, then a weak one.
    - A global unsized symbol (default visibility) inside a sized one is another entry point of
      it (avr-libc: __subsf3 flips a sign and falls into __addsf3; __floatunsisf and __floatsisf
      share their code): the function is named after both, "__subsf3 / __addsf3", and the code
      from there to the next symbol is the function's too.
    - A local label ('.do_clear_bss_loop'), and code past a sized symbol's end without a symbol
      of its own (avr-libc's special cases), belong to the function before them, as avr-objdump
      names them.
    - What no symbol covers (progmem tables) is NO_SYMBOL.

    With LTO, a function inlined into another has no symbol: its cycles are its caller's."""
    data, sections = _elf_sections(elf)
    text_idx = next((i for i, (name, _) in enumerate(sections) if name == ".text"), None)
    symtab = next((sec for name, sec in sections if sec[1] == 2), None)   # SHT_SYMTAB
    if text_idx is None or symtab is None:
        raise UnoSetupError(f"{elf} has no .text or no symbol table: cannot profile it (was it stripped?)")
    text = sections[text_idx][1]
    text_end = text[3] + text[5]
    strtab = sections[symtab[6]][1]
    syms, boundaries = [], set()
    for off in range(symtab[4], symtab[4] + symtab[5], 16):
        st_name, value, size, info, other, shndx = struct.unpack_from("<IIIBBH", data, off)
        if shndx != text_idx or value >= text_end:
            continue
        kind, bind = info & 0xF, info >> 4
        start = strtab[4] + st_name
        name = data[start:data.index(b"\0", start)].decode("ascii", "replace")
        if not name:
            continue
        boundaries.add(value)
        if kind in (0, 2):   # NOTYPE, FUNC; OBJECT (tables in flash) only bounds the labels
            rank = (size > 0, bind == 1, bind == 2, not name.startswith("."), other & 3 == 0)
            syms.append((value, size, rank, name))
    best: dict[int, tuple] = {}
    for sym in sorted(syms, key=lambda t: (t[0], t[3])):
        if sym[0] not in best or sym[2] > best[sym[0]][2]:
            best[sym[0]] = sym
    nwords = (text_end + 1) // 2
    owner = [-1] * nwords
    chosen = sorted(best.values())
    starts_sorted = sorted(boundaries) + [text_end]
    # a sized range ends at the next sized symbol, or at a hidden global label (libgcc's _exit):
    # avr-ld's relaxation shrinks CALLs to RCALLs after avr-libc's sizes were taken
    sized_starts = sorted(v for v, size, r, _n in chosen if size > 0 or (r[1] or r[2]) and not r[4]) + [text_end]
    for i, (value, size, _rank, _name) in enumerate(chosen):
        if size > 0:
            end = min(value + size, next(b for b in sized_starts if b > value))
            for w in range(value // 2, min(nwords, (end + 1) // 2)):
                if owner[w] < 0:
                    owner[w] = i
    entry_words = [0] * nwords
    alias_of: dict[int, list[str]] = {}   # chosen index of a function -> its other entry points
    for i, (value, size, rank, name) in enumerate(chosen):
        if size > 0:
            continue
        w = value // 2
        host = owner[w] if w < nwords else -1
        if host >= 0 and chosen[host][0] != value and rank[1] and rank[3] and rank[4]:
            alias_of.setdefault(host, []).append(name)   # another entry point: code of its host
            entry_words[w] = 1
        elif name.startswith(".") and w > 0 and owner[w - 1] >= 0:
            host = owner[w - 1]                          # a local label goes on its function
        else:
            host = i
        end = next(b for b in starts_sorted if b > value)
        for w in range(value // 2, min(nwords, (end + 1) // 2)):
            if owner[w] < 0:
                owner[w] = host
    # code between a sized function's end and the next symbol (avr-libc's special cases, jumped
    # to from the next function) is the function's before it, as avr-objdump names it
    boundary_words = {b // 2 for b in boundaries}
    for w in range(1, nwords):
        if owner[w] < 0 and owner[w - 1] >= 0 and w not in boundary_words:
            owner[w] = owner[w - 1]
    used = sorted(set(o for o in owner if o >= 0))
    index = {old: new for new, old in enumerate(used)}
    raw = [chosen[i][3] for i in used] + [NO_SYMBOL]
    starts = [chosen[i][0] for i in used] + [0xFFFFFFFF]
    func_of_word = [index[o] if o >= 0 else len(used) for o in owner]
    for i in used:
        entry_words[chosen[i][0] // 2] = 1
    aliases = {index[host]: names for host, names in alias_of.items() if host in index}
    demangled = _demangle(raw[:-1])
    names = [" / ".join([d] + _demangle(aliases[f])) if f in aliases else d for f, d in enumerate(demangled)]
    names.append(NO_SYMBOL)
    handlers = {}
    all_names = {s[3]: s for s in syms}
    for v in range(1, len(VECTORS_328P)):
        sym = all_names.get(f"__vector_{v}")
        handlers[v] = f"__vector_{v}" if sym and sym[1] > 0 and sym[2][1] else "__bad_interrupt"
    return FunctionMap(names, raw, starts, func_of_word, entry_words, handlers)


def short_name(name: str) -> str:
    """A demangled name without its parameters, clone suffixes, anonymous namespaces and the
    rovernav namespace: 'rovernav::core::Rover::step(...) [clone .constprop.3]' -> 'core::Rover::step'."""
    n = re.sub(r"( \[clone [^\]]*\])+$", "", name).replace("(anonymous namespace)::", "")
    n = re.sub(r"\s+const$", "", n)
    if n.endswith(")"):
        depth = 0
        for i in range(len(n) - 1, -1, -1):
            depth += {")": 1, "(": -1}.get(n[i], 0)
            if depth == 0:
                if i > 0:
                    n = n[:i]
                break
    return re.sub(r"^rovernav::", "", n)


# ---------------------------------------------------------------------------- statistics

def _percentile(sorted_values: list[float], q: float) -> float:
    """Nearest-rank percentile of an ascending list (q in 0..100)."""
    if not sorted_values:
        return math.nan
    k = max(0, min(len(sorted_values) - 1, math.ceil(q / 100.0 * len(sorted_values)) - 1))
    return sorted_values[k]


def _summary(values_us: list[float]) -> dict:
    v = sorted(values_us)
    if not v:
        return {"count": 0, "median_us": None, "p99_us": None, "max_us": None}
    n = len(v)
    median = v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])
    return {"count": n, "median_us": round(median, 1), "p99_us": round(_percentile(v, 99), 1),
            "max_us": round(v[-1], 1)}


def _state_name(state: int) -> str:
    try:
        return mg.RoverState(state).name.lower()
    except ValueError:
        return f"state_{state}"


def _flag_names(desc: int) -> list[str]:
    return [name for name, bit in DESC_FLAGS.items() if desc & bit]


# ---------------------------------------------------------------------------- the core

class UnoCore:
    """The Uno image in simavr, a `RoverCore`. Not thread-safe."""

    def __init__(self, boot_id: int = 1, reset_cause: int = 1, *, sonar: Callable[[], int] | None = None,
                 start_ms: int = 0, elf: Path | None = None, fast_forward: bool | None = None,
                 profile: bool = False, key: bytes | None = None):
        self.elf, _ = ensure_built(elf or ELF)
        self._lib = load_library()
        self.board = board_constants()
        self.static_end = static_ram_end(self.elf)
        err = ctypes.create_string_buffer(256)
        handle = self._lib.unocore_new(str(self.elf).encode(), self.static_end, (boot_id - 1) & 0xFFFF,
                                       reset_cause & 0xFF, self.board.mpu_address, self.board.serial_baud,
                                       err, len(err))
        if not handle:
            raise UnoSetupError(f"simavr: {err.value.decode(errors='replace')}")
        self._h = handle
        self._sonar = sonar
        self._sonar_error: BaseException | None = None
        self._sonar_cb = _SONAR_FN(self._on_trigger)   # kept: C holds the pointer
        self._lib.unocore_set_sonar(handle, self._sonar_cb, None)
        if fast_forward is None:   # ROVERNAV_UNO_FAST_FORWARD=0 turns it off (to check it changes nothing)
            fast_forward = os.environ.get("ROVERNAV_UNO_FAST_FORWARD", "1") not in ("0", "no", "off")
        self._lib.unocore_set_fast_forward(handle, int(fast_forward))
        self.start_ms = start_ms
        self._regs = _Regs()
        self._txbuf = ctypes.create_string_buffer(4096)
        self._pings = 0
        self._servo_cdeg = 0
        # The image's own reports, for probe() and the report (never for control); with a link key
        # its frames are signed, and checked here as the host checks them.
        self._key = key
        self._decoder = self._new_decoder()
        self._status: mg.Status | None = None
        self.link_auth: mg.LinkAuth | None = None
        if key is not None:
            self.eeprom(self.board.eeprom_link_addr, link_key_record(key))
        self.sonar_ranges: list[int] = []
        self.wall_s = 0.0             # spent inside the AVR simulation
        self._records: list[tuple[int, int, int, int, int]] = []   # rise, fall, desc, has_desc, boot
        self.crashed = False
        self._fmap: FunctionMap | None = None
        self._final_profile: dict | None = None
        if profile:
            self.enable_profile()

    def enable_profile(self, worst_cap: int = 2048) -> None:
        """From now on, count where the steps' cycles go, by function (unocore.c, "Profile");
        timing() then has a "profile" section. worst_cap: how many of the longest steps keep
        their own counts, for the worst 1 % (enough for 2,000 s of steps)."""
        fmap = function_map(self.elf)
        words = (ctypes.c_uint16 * len(fmap.func_of_word))(*fmap.func_of_word)
        entry = (ctypes.c_uint8 * len(fmap.entry_words))(*fmap.entry_words)
        if self._lib.unocore_profile_start(self._h, words, len(words), entry, len(fmap.names), worst_cap) != 0:
            raise UnoSetupError(f"cannot start the profile ({len(fmap.names)} functions)")
        self._fmap = fmap

    # -------------------------------------------------------------- the sensors' callbacks

    def _on_trigger(self, _user) -> int:
        """TRIG rose: the range the HC-SR04 will report (0 = no echo)."""
        try:
            mm = int(self._sonar()) if self._sonar is not None else 0
        except BaseException as exc:  # raised again after the run: C cannot unwind Python
            self._sonar_error = exc
            return 0
        self.sonar_ranges.append(mm)
        return max(0, min(mm, 0xFFFFFFFF))

    # -------------------------------------------------------------- RoverCore's interface

    def step(self, now_ms: int, *, gyro_rate_mdps: int | None, sonar_range_mm: int | None = None,
             rx: bytes = b"", tx_room: int = mg.UART_BUFFER_BYTES, wheel_ticks: tuple[int, int] | None = None) -> StepOut:
        """Runs the AVR up to now_ms with the gyro reading gyro_rate_mdps (clockwise, None = the
        chip stops answering) and rx queued for its UART; returns what its pins show at now_ms.
        sonar_range_mm, tx_room and wheel_ticks are not used (see the module's docstring)."""
        if self.crashed:
            return StepOut(0, 0, self._servo_cdeg, False, b"")
        lib, h = self._lib, self._h
        alive = gyro_rate_mdps is not None
        # The chip's Z is counter-clockwise-positive: heading rate = sign * chip rate.
        lib.unocore_set_gyro(h, int(alive), self.board.gyro_z_to_clockwise_sign * int(gyro_rate_mdps or 0))
        if rx:
            lib.unocore_rx(h, bytes(rx), len(rx))
        target = max(0, now_ms - self.start_ms) * CYCLES_PER_MS
        started = time.perf_counter()
        stopped = lib.unocore_run_to(h, target)
        self.wall_s += time.perf_counter() - started
        if self._sonar_error is not None:
            exc, self._sonar_error = self._sonar_error, None
            raise exc
        if stopped:
            self.crashed = True
            st = self._stats()
            raise UnoCrashError(f"simavr stopped the AVR at {now_ms / 1000:.3f} s (state {st.cpu_state}, "
                                f"pc 0x{st.crash_pc:04x}, word 0x{st.crash_pc // 2:04x}); "
                                f"disassemble with avr-objdump -d {self.elf}")
        n = lib.unocore_tx(h, self._txbuf, len(self._txbuf))
        tx = ctypes.string_at(self._txbuf, n)
        if tx:
            for frame in self._decoder.feed(tx):
                if isinstance(frame.message, mg.Status):
                    self._status = frame.message
                elif isinstance(frame.message, mg.LinkAuth):
                    self.link_auth = frame.message
        r = self._regs
        lib.unocore_regs_read(h, ctypes.byref(r))
        fired = r.pings != self._pings
        self._pings = r.pings
        left, right = self._motors(r)
        self._servo_cdeg = self._servo(r)
        return StepOut(left, right, self._servo_cdeg, fired, tx)

    def probe(self) -> Probe:
        s = self._status
        r = self._regs
        state = (r.last_desc & DESC_STATE_MASK) if r.has_desc else (s.state if s else 0)
        if s is None:
            return Probe(state, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        # largest eigenvalue of the position covariance, as the core's position_sd_mm()
        a, d = float(s.sd_x_mm) ** 2, float(s.sd_y_mm) ** 2
        b = s.corr_xy_permille / 1000.0 * s.sd_x_mm * s.sd_y_mm
        sd = math.sqrt(max(0.0, 0.5 * (a + d) + math.hypot(0.5 * (a - d), b)))
        return Probe(state, s.fault, s.flags, s.waypoint_index, 0, float(s.x_mm), float(s.y_mm),
                     math.radians(s.heading_cdeg / 100.0), sd, 0.0, float(s.dr_distance_mm))

    def hold_consent_pin(self, held: bool = True) -> None:
        """A jumper from the consent pin (board.h kPinConsent, D7) to GND, on (held) or off: the image
        reads the pin once as it starts, so it counts from the next reset (`reset`) on. It stays
        held across resets until let go, as a jumper does."""
        port, bit = uno_pin_port(self.board.pin_consent)
        if self._lib.unocore_hold_pin_low(self._h, port.encode(), bit, int(held)) != 0:
            raise UnoSetupError(f"simavr cannot hold pin {self.board.pin_consent} (port {port}, bit {bit})")

    def reset(self, reset_cause: int) -> None:
        """A reset of the board (power, button): the EEPROM's boot counter and .noinit survive;
        the firmware finds reset_cause in MCUSR."""
        self._lib.unocore_reset(self._h, reset_cause & 0xFF)
        self._status = None
        self._decoder = self._new_decoder()

    def close(self) -> None:
        if getattr(self, "_h", None):
            self._collect_steps(final=True)
            self._final_stats = self._stats()
            if self._fmap is not None:
                self._final_profile = self.profile()
            self._lib.unocore_free(self._h)
            self._h = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass

    # -------------------------------------------------------------- the pins

    @staticmethod
    def _motors(r: _Regs) -> tuple[int, int]:
        """Signed PWM per side, as motors.cpp drives the L298N inputs: an input's duty is its
        OCR value while the timer drives the pin (COMxx1), else 255 or 0 from the port bit."""
        def duty(tccr: int, com1: int, ocr: int, port: int, ddr: int, bit: int) -> int:
            if tccr & com1:
                return ocr
            return 255 if (ddr & bit) and (port & bit) else 0

        left_back = duty(r.tccr2a, 0x20, r.ocr2b, r.portd, r.ddrd, 1 << 3)    # pin 3, OC2B
        left_fwd = duty(r.tccr0a, 0x20, r.ocr0b, r.portd, r.ddrd, 1 << 5)     # pin 5, OC0B
        right_back = duty(r.tccr0a, 0x80, r.ocr0a, r.portd, r.ddrd, 1 << 6)   # pin 6, OC0A
        right_fwd = duty(r.tccr2a, 0x80, r.ocr2a, r.portb, r.ddrb, 1 << 3)    # pin 11, OC2A
        return left_fwd - left_back, right_fwd - right_back

    def _servo(self, r: _Regs) -> int:
        """The angle (cdeg, clockwise from straight ahead) the Timer1 pulse commands: the inverse
        of servo_timer1.cpp's mapping. Without pulses the servo stays where it was."""
        prescale = {1: 1, 2: 8, 3: 64, 4: 256, 5: 1024}.get(r.tccr1b & 0x07)
        if not (r.tccr1a & 0x80) or prescale is None or r.ocr1a == 0:
            return self._servo_cdeg
        b = self.board
        pulse_us = r.ocr1a * prescale / (CLOCK_HZ / 1_000_000)
        servo_cdeg = (pulse_us - b.servo_pulse_min_us) * 18000.0 / (b.servo_pulse_max_us - b.servo_pulse_min_us)
        return int(round(b.servo_clockwise_sign * (servo_cdeg - 9000 - b.servo_centre_trim_cdeg)))

    # -------------------------------------------------------------- measurements

    def _stats(self) -> _Stats:
        if not getattr(self, "_h", None):
            return self._final_stats
        s = _Stats()
        self._lib.unocore_stats_read(self._h, ctypes.byref(s))
        return s

    def _collect_steps(self, final: bool = False) -> None:
        buf = (_Step * 4096)()
        while True:
            n = self._lib.unocore_steps(self._h, buf, len(buf), int(final))
            self._records.extend((s.rise, s.fall, s.desc, s.has_desc, s.boot) for s in buf[:n])
            if n < len(buf):
                break

    def _new_decoder(self) -> FrameDecoder:
        return FrameDecoder(None if self._key is None else Verifier(self._key, SIGN_ROVER_TO_HOST, require=False))

    def auth_counters(self) -> dict[str, int]:
        """Frames the image refused for their signature, as its last LINK_AUTH said."""
        a = self.link_auth
        return {name: getattr(a, name) if a else 0 for name in ("bad_tag", "replayed", "not_signed", "unverified")}

    def eeprom(self, offset: int, data: bytes | None = None, size: int = 0) -> bytes:
        """Writes data to the EEPROM at offset (before the image runs: what it finds at boot), or
        reads size bytes from there; returns what is there afterwards."""
        n = len(data) if data is not None else size
        buf = ctypes.create_string_buffer(bytes(data) if data is not None else bytes(n), n)
        if self._lib.unocore_eeprom(self._h, offset, buf, n, int(data is not None)) != 0:
            raise ValueError(f"EEPROM bytes {offset}..{offset + n} are outside the ATmega328P's 1,024")
        if data is not None:
            self._lib.unocore_eeprom(self._h, offset, buf, n, 0)
        return buf.raw[:n]

    def peek(self, addr: int) -> int:
        """One byte of the AVR's data space (registers, I/O, SRAM)."""
        return self._lib.unocore_peek(self._h, addr)

    def stats(self) -> dict:
        s = self._stats()
        return {name: getattr(s, name) for name, _ in _Stats._fields_ if name != "pad"}

    def timing(self) -> dict:
        """The report's "uno_timing" section (times in microseconds of simulated time)."""
        if getattr(self, "_h", None):
            self._collect_steps(final=True)
        s = self._stats()
        us = 1e6 / CLOCK_HZ
        records = self._records
        with_desc = [r for r in records if r[3]]
        all_us = [(r[1] - r[0]) * us for r in records]
        by_state: dict[str, list[float]] = {}
        for r in with_desc:
            by_state.setdefault(_state_name(r[2] & DESC_STATE_MASK), []).append((r[1] - r[0]) * us)
        by_flag = {name: [(r[1] - r[0]) * us for r in with_desc if r[2] & bit] for name, bit in DESC_FLAGS.items()}
        worst = None
        if records:
            w = max(records, key=lambda r: r[1] - r[0])
            worst = {"us": round((w[1] - w[0]) * us, 1), "t_s": round(self.start_ms / 1000 + w[0] / CLOCK_HZ, 4),
                     "state": _state_name(w[2] & DESC_STATE_MASK) if w[3] else None,
                     "flags": _flag_names(w[2]) if w[3] else None}
        periods = [(b[0] - a[0]) * us for a, b in zip(records, records[1:]) if a[4] == b[4]]
        jitter = sorted(abs(p - STEP_US) for p in periods)
        simulated_s = s.cycle / CLOCK_HZ
        lowest = s.stack_lowest
        painted = s.paint_start and s.paint_start <= s.ramend
        stack = {"ram_end": f"0x{s.ramend:04X}", "static_end": f"0x{s.paint_start:04X}",
                 "static_bytes": s.paint_start - 0x100,
                 "used_bytes": (s.ramend + 1 - lowest) if painted else None,
                 "margin_bytes": (lowest - s.paint_start) if painted else None,
                 "lowest_address": f"0x{lowest:04X}" if painted else None}
        return {
            "image": str(self.elf.relative_to(ROOT) if self.elf.is_relative_to(ROOT) else self.elf),
            "clock_hz": CLOCK_HZ,
            "hooks": {"step_probe_pb0": bool(records), "descriptor_gpior0": bool(with_desc)},
            "steps": len(records),
            "step_time": _summary(all_us),
            "by_state": {k: _summary(v) for k, v in sorted(by_state.items())},
            "by_flag": {k: _summary(v) for k, v in by_flag.items()},
            "worst_step": worst,
            "period_jitter": {"periods": len(periods),
                              "mean_period_us": round(sum(periods) / len(periods), 1) if periods else None,
                              "max_abs_us": round(jitter[-1], 1) if jitter else None,
                              "p99_abs_us": round(_percentile(jitter, 99), 1) if jitter else None},
            "stack": stack,
            "gyro": {"addressed": s.twi_addressed, "whoami_reads": s.twi_whoami_reads,
                     "gyro_reads": s.twi_gyro_reads, "nacked": s.twi_nacked,
                     "workarounds": {"sla_w_status_fixed": s.twi_status_fixed,
                                     "twint_cleared": s.twi_twint_cleared,
                                     "twsto_cleared": s.twi_twsto_cleared}},
            "sonar": {"pings": s.pings, "echoes": s.echoes, "ignored_while_busy": s.pings_ignored},
            "uart": {"bytes_in": s.uart_bytes_in, "bytes_out": s.uart_bytes_out, "xoff": s.uart_xoffs},
            "resets": s.resets,
            "speed": {"simulated_s": round(simulated_s, 3), "avr_wall_s": round(self.wall_s, 3),
                      "avr_x_real_time": round(simulated_s / self.wall_s, 2) if self.wall_s > 0 else None,
                      "idle_fast_forward_share": round(s.skipped_cycles / s.cycle, 3) if s.cycle else None},
            **({"profile": self.profile()} if self._fmap is not None else {}),
        }

    # -------------------------------------------------------------- the profile

    def _profile_arrays(self):
        """(info, {kind: (self, calls, inclusive, edge calls, edge inclusive)}, worst steps): the
        first three by (context, function), the edges by (caller, callee), all as floats."""
        import numpy as np

        lib, h = self._lib, self._h
        info = _ProfInfo()
        lib.unocore_profile_info(h, ctypes.byref(info))
        nkeys, nfn, nf = info.nkeys, info.nctx * info.nfuncs, info.nfuncs
        kinds = {}
        for k, name in enumerate(PROF_KINDS):
            bufs = [(ctypes.c_uint64 * nkeys)() for _ in range(3)]
            if lib.unocore_profile_read(h, k, *bufs, nkeys) != nkeys:
                raise RuntimeError("unocore_profile_read failed")
            cyc, cal, inc = (np.frombuffer(b, dtype=np.uint64).astype(np.float64) for b in bufs)
            edges = (cal[nfn:].reshape(nf, nf), inc[nfn:].reshape(nf, nf)) if info.nedges else \
                (np.zeros((nf, nf)), np.zeros((nf, nf)))
            kinds[name] = (cyc[:nfn].reshape(info.nctx, nf), cal[:nfn].reshape(info.nctx, nf),
                           inc[:nfn].reshape(info.nctx, nf), *edges)
        worst = []
        hdr = _ProfStep()
        entries = (_ProfEntry * nkeys)()
        for i in range(info.worst_kept):
            n = lib.unocore_profile_worst(h, i, ctypes.byref(hdr), entries, nkeys)
            worst.append((hdr.fall - hdr.rise, hdr.rise, hdr.desc if hdr.has_desc else None,
                          [(e.key, e.cycles, e.calls, e.incl) for e in entries[:n]]))
        return info, kinds, worst

    def profile(self) -> dict:
        """uno_timing["profile"]: where the steps' cycles go (see unocore.c, "Profile").

        For each kind of step (all, fix, sonar, replanning, radio_rx, no_flags: by the GPIOR0
        descriptor; worst_1pct: the longest 1 % of all steps; worst_step: the longest one):
        - `steps`, `mean_step_us`; `counted_share` (cycles counted / cycles between PB0's edges:
          1.0 when nothing is missed) and `named_share` (the share of those inside a named function);
        - `functions`: the top 15 of the main line by self cycles (at PCs inside the function),
          with their share of the step time, microseconds per step, calls per step (arrivals at an
          entry point from another function) and inclusive microseconds per step (CALL to RET,
          interrupts left out);
        - `inclusive`: the top 15 by inclusive time; `calls`: the top 15 caller -> callee edges
          of the firmware's own functions by inclusive time (library-internal calls left out);
        - `interrupts`: each handler with everything it ran, apart from the main line;
        - `float_library`, `integer_library` (avr-libc, libgcc): together, one by one, and the
          firmware functions that call into them.
        Shares are of the step time of that kind of step; microseconds are per step of it."""
        if self._fmap is None:
            return {}
        if not getattr(self, "_h", None):
            return self._final_profile or {}
        fmap = self._fmap
        info, kinds, worst = self._profile_arrays()
        out: dict = {
            "method": "per instruction (exact, not sampled): while PB0 is high, each instruction's cycles go to "
                      "the function whose ELF symbol holds its PC (self); an interrupt's cycles (its entry, its "
                      "handler and what that calls) to the interrupt; inclusive times from a shadow call stack "
                      "(CALL to RET, interrupts left out)",
            "symbols": len(fmap.names) - 1,
            "instructions_counted": info.instructions,
            "kinds": {},
        }
        for k, name in enumerate(PROF_KINDS):
            out["kinds"][name] = self._profile_kind(kinds[name], info.steps[k], info.step_cycles[k],
                                                    info.attributed[k])
        # the worst 1 % of all steps, and the single worst, from the longest steps the harness kept
        n_all = info.steps[0]
        n_worst = max(1, math.ceil(n_all / 100)) if n_all else 0
        ranked = sorted(worst, key=lambda w: (-w[0], w[1]))
        out["kinds"]["worst_1pct"] = self._profile_chosen(info, ranked[:n_worst], n_worst)
        out["kinds"]["worst_step"] = self._profile_chosen(info, ranked[:1], 1 if n_all else 0)
        # the shadow call stack's health: frames open when a step ended (main's code raises
        # and lowers PB0, so 0 when every call met its return), calls too deep to follow
        out["open_frames_at_step_end"] = info.open_frames
        if info.depth_lost:
            out["calls_too_deep"] = info.depth_lost
        return out

    def _profile_chosen(self, info, chosen: list, wanted: int) -> dict:
        """_profile_kind over some of the longest steps the harness kept (their own counts)."""
        import numpy as np

        nf, nfn = info.nfuncs, info.nctx * info.nfuncs
        cyc, cal, inc = (np.zeros((info.nctx, nf)) for _ in range(3))
        ecal, einc = np.zeros((nf, nf)), np.zeros((nf, nf))
        for _dur, _rise, _desc, entries in chosen:
            for key, c, n, i in entries:
                if key >= nfn:
                    caller, callee = divmod(key - nfn, nf)
                    ecal[caller, callee] += n
                    einc[caller, callee] += i
                    continue
                ctx, f = divmod(key, nf)
                cyc[ctx, f] += c
                cal[ctx, f] += n
                inc[ctx, f] += i
        w = self._profile_kind((cyc, cal, inc, ecal, einc), len(chosen), sum(c[0] for c in chosen),
                               float(cyc.sum()))
        if chosen:
            w["threshold_us"] = round(chosen[-1][0] * 1e6 / CLOCK_HZ, 1)
            w["flags"] = {flag: sum(1 for c in chosen if c[2] is not None and c[2] & bit)
                          for flag, bit in DESC_FLAGS.items()}
        if len(chosen) < wanted:
            w["note"] = f"only the {len(chosen)} longest steps were kept (worst_cap)"
        return w

    def _profile_kind(self, arrays, steps: int, step_cycles: int, attributed: float) -> dict:
        import numpy as np

        cyc, cal, inc, ecal, einc = arrays
        if not steps:
            return {"steps": 0}
        fmap = self._fmap
        us = 1e6 / CLOCK_HZ
        nosym = fmap.no_symbol

        frames_of = ecal.sum(axis=0)   # main-line frames opened for each function (CALLs, tail calls)

        def row(name: str, cycles: float, calls: float | None = None, incl: float | None = None,
                frames: float | None = None) -> dict:
            r = {"function": short_name(name), "symbol": name, "cycles": int(cycles),
                 "share": round(float(cycles) / step_cycles, 4), "us_per_step": round(float(cycles) * us / steps, 1)}
            if calls is not None:
                r["calls_per_step"] = round(float(calls) / steps, 2)
            if incl is not None and incl > 0:
                r["inclusive_us_per_step"] = round(float(incl) * us / steps, 1)
                r["inclusive_share"] = round(float(incl) / step_cycles, 4)
                if frames is not None and frames > 0:   # per frame: per CALL (or tail call) to it
                    r["inclusive_us_per_call"] = round(float(incl) * us / float(frames), 1)
            return r

        main_self, main_calls, main_incl = cyc[0], cal[0], inc[0]
        top_self = [int(f) for f in main_self.argsort()[::-1][:15] if main_self[f] > 0]
        top_incl = [int(f) for f in main_incl.argsort()[::-1][:15] if main_incl[f] > 0]
        interrupts = []
        for ctx in range(1, cyc.shape[0]):
            total = float(cyc[ctx].sum())
            if total <= 0:
                continue
            handler = fmap.vector_handlers.get(ctx, f"__vector_{ctx}")
            entries = sum(cal[ctx, f] for f, n in enumerate(fmap.names) if n == handler) if handler else 0
            inside = [int(f) for f in cyc[ctx].argsort()[::-1][:5] if cyc[ctx, f] > 0]
            interrupts.append({
                "vector": ctx, "source": VECTORS_328P[ctx] if ctx < len(VECTORS_328P) else None,
                "handler": handler, "cycles": int(total), "share": round(total / step_cycles, 4),
                "us_per_step": round(total * us / steps, 1), "entries_per_step": round(float(entries) / steps, 2),
                "functions": [{"function": short_name(fmap.names[f]), "cycles": int(cyc[ctx, f])} for f in inside]})
        interrupts.sort(key=lambda r: -r["cycles"])

        float_fs = [f for f, raw in enumerate(fmap.raw_names) if FLOAT_LIBRARY.match(raw)]
        int_fs = [f for f, raw in enumerate(fmap.raw_names) if INTEGER_LIBRARY.match(raw)]
        library_fs = set(float_fs) | set(int_fs)
        firmware_fs = [f for f in range(len(fmap.names)) if f not in library_fs]

        def edge(caller: int, callee_name: str, calls: float, incl: float) -> dict:
            return {"caller": short_name(fmap.names[caller]), "callee": callee_name,
                    "calls_per_step": round(calls / steps, 2), "inclusive_us_per_step": round(incl * us / steps, 1),
                    "inclusive_share": round(incl / step_cycles, 4)}

        def library(fs: list[int]) -> dict:
            per = sorted(((float(cyc[:, f].sum()), float(cal[:, f].sum()), f) for f in fs), reverse=True)
            total = sum(c for c, _, _ in per)
            # who calls into the library: the firmware's functions (main line), inclusive time
            into = einc[np.ix_(firmware_fs, fs)].sum(axis=1)
            n_into = ecal[np.ix_(firmware_fs, fs)].sum(axis=1)
            callers = [edge(firmware_fs[i], "(library)", float(n_into[i]), float(into[i]))
                       for i in into.argsort()[::-1][:10] if into[i] > 0]
            return {"cycles": int(total), "share": round(total / step_cycles, 4),
                    "us_per_step": round(total * us / steps, 1),
                    "functions": [row(fmap.names[f], c, n, inc[0, f], frames_of[f]) for c, n, f in per if c > 0],
                    "callers": callers}

        # the firmware's calls (library-internal ones left out), by inclusive time
        fw_einc = einc[firmware_fs, :]
        order = np.dstack(np.unravel_index(fw_einc.ravel().argsort()[::-1][:15], fw_einc.shape))[0]
        call_edges = [edge(firmware_fs[i], short_name(fmap.names[j]), float(ecal[firmware_fs[i], j]),
                           float(einc[firmware_fs[i], j])) for i, j in order if fw_einc[i, j] > 0]

        return {
            "steps": int(steps),
            "mean_step_us": round(step_cycles * us / steps, 1),
            "counted_share": round(attributed / step_cycles, 4),
            "named_share": round(1 - float(cyc[:, nosym].sum()) / attributed, 4) if attributed else None,
            "interrupt_share": round(sum(r["cycles"] for r in interrupts) / step_cycles, 4),
            "functions": [row(fmap.names[f], main_self[f], main_calls[f], main_incl[f], frames_of[f])
                          for f in top_self],
            "inclusive": [{"function": short_name(fmap.names[f]), "symbol": fmap.names[f],
                           "inclusive_share": round(float(main_incl[f]) / step_cycles, 4),
                           "inclusive_us_per_step": round(float(main_incl[f]) * us / steps, 1),
                           "calls_per_step": round(float(main_calls[f]) / steps, 2)} for f in top_incl],
            "calls": call_edges,
            "interrupts": interrupts,
            "float_library": library(float_fs),
            "integer_library": library(int_fs),
        }
