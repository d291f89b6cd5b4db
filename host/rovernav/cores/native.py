"""The rover's firmware core, loaded from its C ABI (firmware/abi/rover_abi.h) with ctypes.

The simulator and the tests step the very code the Uno runs: `NativeCore.step()` (a
`rovernav.cores.protocol.RoverCore`) passes one
tick of sensor readings and received bytes in, and returns the motor commands, the servo
angle, whether to ping, and the bytes the rover sends. `build_library()` compiles the shared
library from the checkout's firmware sources with CMake when it is missing or stale.
"""

from __future__ import annotations

import ctypes
import logging
import shutil
import subprocess
from pathlib import Path

from ..link.messages_gen import MAX_ROVERS
from .abi_gen import (
    ROVER_ABI_CONSTANTS,
    ROVER_ABI_STRUCTS,
    ROVER_ABI_VERSION,
    ROVER_TX_PER_STEP,
    RoverInputs,
    RoverOutputs,
    RoverProbe,
)
from .protocol import FirmwareBuildError, Probe, StepOut

log = logging.getLogger("rovernav.cores.native")

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware"
BUILD_DIR = ROOT / "build" / "native"
LIBRARY = BUILD_DIR / "librovernav_rover.so"
ABI_VERSION = ROVER_ABI_VERSION
TX_PER_STEP = ROVER_TX_PER_STEP  # a step hands the shell at most one UART buffer (rover_abi.cpp asserts it)


#: rover_abi.h's structs, generated with it from firmware/abi/abi.toml (firmware/abi/generate.py).
STRUCTS = ROVER_ABI_STRUCTS


def python_layout(structs=STRUCTS) -> list[int]:
    """What rover_abi_layout() says (ROVER_ABI_LAYOUT_WORDS), computed by ctypes from the generated copies
    of the structs."""
    words = [ctypes.sizeof(st) for st in structs] + list(ROVER_ABI_CONSTANTS.values())
    for st in structs:
        words += [getattr(st, name).offset for name, _type in st._fields_]
    return words


def check_layout(lib, structs=STRUCTS) -> None:
    """FirmwareBuildError, naming the first field that differs, when the library's structs are not
    laid out as the generated ctypes copies (a library built from another firmware/abi/abi.toml, or
    a compiler that lays them out otherwise than ctypes)."""
    n = 64
    buf = (ctypes.c_uint32 * n)()
    count = lib.rover_abi_layout(buf, n)
    theirs, ours = list(buf[: min(count, n)]), python_layout(structs)
    if theirs == ours:
        return
    c_name = [getattr(st, "_c_name_", st.__name__) for st in structs]
    names = (
        [f"sizeof({n})" for n in c_name]
        + list(ROVER_ABI_CONSTANTS)
        + [f"{n}.{name}" for n, st in zip(c_name, structs) for name, _type in st._fields_]
    )
    for i, (a, b) in enumerate(zip(theirs, ours)):
        if a != b:
            raise FirmwareBuildError(
                f"the library's rover_abi.h and host/rovernav/cores/abi_gen.py disagree: "
                f"{names[i]} is {a} there, {b} here (rebuild the library, or run "
                "python3 firmware/abi/generate.py)"
            )
    raise FirmwareBuildError(
        f"the library's rover_abi.h and host/rovernav/cores/abi_gen.py disagree: {count} layout "
        f"words there, {len(ours)} here (a field added on one side only)"
    )


def _sources() -> list[Path]:
    """What the library is built from: a newer one (or a new file: CMake globs the directories
    with CONFIGURE_DEPENDS) rebuilds it."""
    return [FIRMWARE / "CMakeLists.txt"] + [
        p for d in ("lib/core", "lib/link", "abi") for p in (FIRMWARE / d).glob("*") if p.suffix in (".cpp", ".h")
    ]


def build_library(force: bool = False) -> Path:
    """Build librovernav_rover.so with CMake if it is missing or older than a source; return its path.
    One process builds at a time (the others wait, then find it built)."""
    if not FIRMWARE.is_dir():
        raise FirmwareBuildError(f"no firmware sources under {ROOT}: the core is built from a checkout")
    from ..files import build_lock

    with build_lock(BUILD_DIR):
        return _build_library(force)


def _build_library(force: bool) -> Path:
    newest = max(p.stat().st_mtime for p in _sources())
    if not force and LIBRARY.exists() and LIBRARY.stat().st_mtime >= newest:
        return LIBRARY
    if shutil.which("cmake") is None:
        raise FirmwareBuildError("cmake is not installed (apt-get install cmake g++)")
    log.info("building the firmware core library in %s", BUILD_DIR)
    commands = [["cmake", "--build", str(BUILD_DIR), "--target", "rovernav_rover", "-j2"]]
    if not (BUILD_DIR / "CMakeCache.txt").exists():  # else keep the configuration scripts/test made
        commands.insert(0, ["cmake", "-S", str(FIRMWARE), "-B", str(BUILD_DIR), "-DCMAKE_BUILD_TYPE=Release"])
    for cmd in commands:
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise FirmwareBuildError(f"{' '.join(cmd[:2])} failed:\n{(result.stdout + result.stderr)[-2000:]}")
    return LIBRARY


_lib: ctypes.CDLL | None = None


def load_library() -> ctypes.CDLL:
    """The loaded ABI library (built first if needed); checks its ABI version and schema hash."""
    global _lib
    if _lib is not None:
        return _lib
    lib = ctypes.CDLL(str(build_library()))
    lib.rover_abi_version.restype = ctypes.c_uint32
    lib.rover_schema_hash.restype = ctypes.c_uint32
    lib.rover_new.restype = ctypes.c_void_p
    lib.rover_new.argtypes = [ctypes.c_uint32, ctypes.c_uint16]
    lib.rover_new_keyed.restype = ctypes.c_void_p
    lib.rover_new_keyed.argtypes = [
        ctypes.c_uint32,
        ctypes.c_uint16,
        ctypes.c_char_p,
        ctypes.c_uint64,
        ctypes.c_uint64,
        ctypes.c_uint8,
    ]
    lib.rover_fleet_id.restype = ctypes.c_int
    lib.rover_fleet_id.argtypes = [ctypes.c_void_p]
    lib.rover_take_persist.restype = ctypes.c_int
    lib.rover_take_persist.argtypes = [
        ctypes.c_void_p,
        ctypes.POINTER(ctypes.c_uint64),
        ctypes.POINTER(ctypes.c_uint64),
    ]
    lib.rover_take_key_change.restype = ctypes.c_int
    lib.rover_take_key_change.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
    lib.rover_auth_counters.restype = None
    lib.rover_auth_counters.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint16)]
    lib.rover_step.argtypes = [ctypes.c_void_p, ctypes.POINTER(RoverInputs), ctypes.POINTER(RoverOutputs)]
    lib.rover_step.restype = None
    lib.rover_probe_state.argtypes = [ctypes.c_void_p, ctypes.POINTER(RoverProbe)]
    lib.rover_probe_state.restype = None
    lib.rover_free.argtypes = [ctypes.c_void_p]
    lib.rover_free.restype = None
    if lib.rover_abi_version() != ABI_VERSION:
        raise FirmwareBuildError(f"{LIBRARY} has ABI version {lib.rover_abi_version()}, expected {ABI_VERSION}")
    lib.rover_abi_layout.restype = ctypes.c_uint32
    lib.rover_abi_layout.argtypes = [ctypes.POINTER(ctypes.c_uint32), ctypes.c_uint32]
    check_layout(lib)
    from ..link.messages_gen import SCHEMA_HASH

    if lib.rover_schema_hash() != SCHEMA_HASH:
        raise FirmwareBuildError(
            f"{LIBRARY} was built from another protocol definition "
            f"(0x{lib.rover_schema_hash():08X}, ours 0x{SCHEMA_HASH:08X}): rebuild it"
        )
    _lib = lib
    return lib


class NativeCore:
    """One rover: the firmware core behind its C ABI (a `RoverCore`). Not thread-safe; step it
    from one thread."""

    RX_HELD_MAX = 255  # bytes held for the core, like the Uno's buffers: more are dropped

    def __init__(
        self,
        boot_id: int = 1,
        reset_cause: int = 0,
        *,
        key: bytes | None = None,
        counters: tuple[int, int] = (0, 0),
        fleet_id: int = 0,
    ):
        """key: the 16-byte link key in the rover's store (None: none, the link unsigned);
        counters: its stored signing counters (tx, rx), as `take_persist` last gave them;
        fleet_id: the fleet id stored with the key (0: a lone rover; 1..4: rover k of a fleet, at
        address k - 1, which speaks only when spoken to: [fleet] of protocol/messages.toml)."""
        self._handle = None
        if isinstance(fleet_id, bool) or not isinstance(fleet_id, int) or not 0 <= fleet_id <= MAX_ROVERS:
            raise ValueError(f"a fleet id is 0 (a lone rover) or 1..{MAX_ROVERS}, got {fleet_id!r}")
        self._lib = load_library()
        if key is None and counters == (0, 0) and fleet_id == 0:
            self._handle = self._lib.rover_new(boot_id & 0xFFFFFFFF, reset_cause & 0xFFFF)
        else:
            if key is not None and len(key) != 16:
                raise ValueError(f"a link key is 16 bytes, got {len(key)}")
            self._handle = self._lib.rover_new_keyed(
                boot_id & 0xFFFFFFFF, reset_cause & 0xFFFF, key, counters[0], counters[1], fleet_id
            )
        self._in = RoverInputs()
        self._out = RoverOutputs()
        self._rx = (ctypes.c_uint8 * 255)()
        self._held = b""  # bytes the core has not taken yet (one signed frame a step)
        self.rx_dropped = 0  # bytes that found the buffer full

    def take_persist(self) -> tuple[int, int] | None:
        """The signing counters (tx, rx) the rover asks its store to keep now, else None."""
        tx, rx = ctypes.c_uint64(), ctypes.c_uint64()
        if self._lib.rover_take_persist(self._handle, ctypes.byref(tx), ctypes.byref(rx)):
            return tx.value, rx.value
        return None

    @property
    def fleet_id(self) -> int:
        """The fleet id the rover holds: its store's, or the last PROVISION's (what its shell would store
        with the key): 0 a lone rover, k rover k of a fleet (address k - 1)."""
        return self._lib.rover_fleet_id(self._handle)

    def take_key_change(self) -> tuple[str, bytes | None] | None:
        """A PROVISION the rover took: ("store", key) or ("erase", None); else None."""
        buf = ctypes.create_string_buffer(16)
        change = self._lib.rover_take_key_change(self._handle, buf)
        return {0: None, 1: ("store", buf.raw), 2: ("erase", None)}[change]

    def auth_counters(self) -> dict[str, int]:
        """Frames the rover refused for their signature, by reason."""
        out = (ctypes.c_uint16 * 4)()
        self._lib.rover_auth_counters(self._handle, out)
        return dict(zip(("bad_tag", "replayed", "not_signed", "unverified"), out))

    def step(
        self,
        now_ms: int,
        *,
        gyro_rate_mdps: int | None,
        sonar_range_mm: int | None = None,
        rx: bytes = b"",
        tx_room: int = TX_PER_STEP,
        wheel_ticks: tuple[int, int] | None = None,
    ) -> StepOut:
        """One tick. gyro_rate_mdps None = no gyro sample; sonar_range_mm None = no ping result
        this tick (0 = a ping with no echo); rx: the bytes received since the last step, given
        to the core after any it left last time (a core with a key takes one signed frame a
        step), up to RX_HELD_MAX held; returns what the rover asked."""
        room = self.RX_HELD_MAX - len(self._held)
        if len(rx) > room:
            self.rx_dropped += len(rx) - room
        rx = self._held + bytes(rx[:room])
        i = self._in
        i.now_ms = now_ms & 0xFFFFFFFF
        i.gyro_valid = gyro_rate_mdps is not None
        i.gyro_rate_mdps = int(gyro_rate_mdps or 0)
        i.sonar_valid = sonar_range_mm is not None
        i.sonar_range_mm = int(sonar_range_mm or 0)
        i.wheels_valid = wheel_ticks is not None
        i.left_ticks, i.right_ticks = wheel_ticks or (0, 0)
        ctypes.memmove(self._rx, rx, len(rx))
        i.rx = self._rx
        i.rx_len = len(rx)
        i.tx_room = max(0, min(255, tx_room))
        self._lib.rover_step(self._handle, ctypes.byref(i), ctypes.byref(self._out))
        o = self._out
        self._held = rx[o.rx_used :]
        return StepOut(o.left_pwm, o.right_pwm, o.servo_cdeg, bool(o.fire_sonar), bytes(o.tx[: o.tx_len]))

    def probe(self) -> Probe:
        p = RoverProbe()
        self._lib.rover_probe_state(self._handle, ctypes.byref(p))
        return Probe(
            p.state,
            p.fault,
            p.flags,
            p.waypoint_index,
            p.waypoint_count,
            p.x_mm,
            p.y_mm,
            p.heading_rad,
            p.position_sd_mm,
            p.speed_scale,
            p.dr_distance_mm,
        )

    def close(self) -> None:
        if self._handle:
            self._lib.rover_free(self._handle)
            self._handle = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass
