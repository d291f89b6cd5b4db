"""The Uno image itself as the simulated rover's firmware: `rovernav sim --rover uno`.

`UnoCore` runs build/uno/firmware.elf in simavr (tools/avrsim/unocore.c, loaded from
build/avrsim/libunocore.so with ctypes: rovernav.cores.uno_harness) with the simulated world on
its pins, and is a `rovernav.cores.protocol.RoverCore` like `rovernav.cores.native.NativeCore`,
so the simulator's loop (sim/runner.py) steps either one:

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
  (rovernav.cores.elf.function_map), for all steps, the steps with a FIX, with sonar, ..., and
  the worst 1 % (rovernav.cores.profile). The harness counts every instruction executed while
  PB0 is high (see unocore.c, "Profile").

Time: the AVR's cycle 0 is the simulated time the core was made at; step(now_ms) runs it to
(now_ms - start_ms) * 16,000 cycles, so its outputs at `now` are what its pins showed at `now`,
and the plant moves under them for the next 10 ms, as with the native core.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import os
import re
import time
from collections.abc import Callable
from pathlib import Path

from ..link import messages_gen as mg
from ..link.framing import FrameDecoder, Verifier, crc16
from ..link.messages_gen import SIGN_ROVER_TO_HOST
from .elf import FunctionMap, static_ram_end
from .profile import read_profile, start_profile
from .protocol import Probe, StepOut
from .uno_harness import (
    _SONAR_FN,
    BOARD_H,
    CLOCK_HZ,
    CYCLES_PER_MS,
    DESC_FLAGS,
    DESC_STATE_MASK,
    ELF,
    ROOT,
    STEP_US,
    VEHICLE_H,
    UnoSetupError,
    _Regs,
    _Stats,
    _Step,
    ensure_built,
    load_library,
)


class UnoCrashError(RuntimeError):
    """simavr stopped the AVR core (an illegal instruction, a jump out of the flash)."""


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
    pin_consent: int  # held to GND at a reset: the owner's consent to a new link key


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
    """board.h's numbers. A constant given as another's name (kSerialBaud = kLinkBaud) is looked up
    in board.h, then in the vehicle's facts it includes (firmware/lib/link/vehicle_gen.h)."""
    text = path.read_text(encoding="utf-8")
    if VEHICLE_H.is_file():
        text += "\n" + VEHICLE_H.read_text(encoding="utf-8")

    def value(name: str, depth: int = 0) -> int:
        m = re.search(rf"\b{name}\s*=\s*(-?(?:0x[0-9A-Fa-f]+|\d+)|k[A-Za-z0-9_]+)\s*[;,]", text)
        if m is None or depth > 4:
            raise UnoSetupError(f"{path}: no constant {name}")
        if m.group(1).startswith("k"):
            return value(m.group(1), depth + 1)
        return int(m.group(1), 0)

    return Board(
        value("kServoPulseMinUs"),
        value("kServoPulseMaxUs"),
        value("kServoCentreTrimCdeg"),
        value("kServoClockwiseSign"),
        value("kGyroZToClockwiseSign"),
        value("kMpuAddress"),
        value("kSerialBaud"),
        value("kEepromLinkAddr"),
        value("kPinConsent"),
    )


def link_key_record(key: bytes | None, fleet_id: int = 0) -> bytes:
    """The key record firmware/lib/hal/link_store.h keeps in EEPROM: 0xA5 and the key (0xFF and
    0xFF's: none), and their CRC-16 xor the fleet id ([fleet]: 0 a lone rover, 1..MAX_ROVERS rover
    k of a fleet; a lone rover's record is the one written before fleets)."""
    if not 0 <= fleet_id <= mg.MAX_ROVERS:
        raise ValueError(f"a fleet id is 0..{mg.MAX_ROVERS}, got {fleet_id}")
    rec = b"\xa5" + bytes(key) if key is not None else b"\xff" * 17
    return rec + (crc16(rec) ^ fleet_id).to_bytes(2, "little")


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
    return {
        "count": n,
        "median_us": round(median, 1),
        "p99_us": round(_percentile(v, 99), 1),
        "max_us": round(v[-1], 1),
    }


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

    def __init__(
        self,
        boot_id: int = 1,
        reset_cause: int = 1,
        *,
        sonar: Callable[[], int] | None = None,
        start_ms: int = 0,
        elf: Path | None = None,
        fast_forward: bool | None = None,
        profile: bool = False,
        key: bytes | None = None,
        fleet_id: int = 0,
    ):
        """key: the link key in the image's EEPROM (None: none); fleet_id: the fleet id stored with
        it (0: a lone rover; 1..4: rover k of a fleet, at address k - 1, which speaks only when
        spoken to: [fleet] of protocol/messages.toml)."""
        record = link_key_record(key, fleet_id) if key is not None or fleet_id else None  # checked first
        self.elf, _ = ensure_built(elf or ELF)
        self._lib = load_library()
        self.board = board_constants()
        self.static_end = static_ram_end(self.elf)
        err = ctypes.create_string_buffer(256)
        handle = self._lib.unocore_new(
            str(self.elf).encode(),
            self.static_end,
            (boot_id - 1) & 0xFFFF,
            reset_cause & 0xFF,
            self.board.mpu_address,
            self.board.serial_baud,
            err,
            len(err),
        )
        if not handle:
            raise UnoSetupError(f"simavr: {err.value.decode(errors='replace')}")
        self._h = handle
        self._sonar = sonar
        self._sonar_error: BaseException | None = None
        self._sonar_cb = _SONAR_FN(self._on_trigger)  # kept: C holds the pointer
        self._lib.unocore_set_sonar(handle, self._sonar_cb, None)
        if fast_forward is None:  # ROVERNAV_UNO_FAST_FORWARD=0 turns it off (to check it changes nothing)
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
        if record is not None:
            self.eeprom(self.board.eeprom_link_addr, record)
        self.sonar_ranges: list[int] = []
        self.wall_s = 0.0  # spent inside the AVR simulation
        self._records: list[tuple[int, int, int, int, int]] = []  # rise, fall, desc, has_desc, boot
        self.crashed = False
        self._fmap: FunctionMap | None = None
        self._final_profile: dict | None = None
        if profile:
            self.enable_profile()

    def enable_profile(self, worst_cap: int = 2048) -> None:
        """From now on, count where the steps' cycles go, by function (unocore.c, "Profile");
        timing() then has a "profile" section. worst_cap: how many of the longest steps keep
        their own counts, for the worst 1 % (enough for 2,000 s of steps)."""
        self._fmap = start_profile(self._lib, self._h, self.elf, worst_cap)

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

    def step(
        self,
        now_ms: int,
        *,
        gyro_rate_mdps: int | None,
        sonar_range_mm: int | None = None,
        rx: bytes = b"",
        tx_room: int = mg.UART_BUFFER_BYTES,
        wheel_ticks: tuple[int, int] | None = None,
    ) -> StepOut:
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
            raise UnoCrashError(
                f"simavr stopped the AVR at {now_ms / 1000:.3f} s (state {st.cpu_state}, "
                f"pc 0x{st.crash_pc:04x}, word 0x{st.crash_pc // 2:04x}); "
                f"disassemble with avr-objdump -d {self.elf}"
            )
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
        return Probe(
            state,
            s.fault,
            s.flags,
            s.waypoint_index,
            0,
            float(s.x_mm),
            float(s.y_mm),
            math.radians(s.heading_cdeg / 100.0),
            sd,
            0.0,
            float(s.dr_distance_mm),
        )

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

        left_back = duty(r.tccr2a, 0x20, r.ocr2b, r.portd, r.ddrd, 1 << 3)  # pin 3, OC2B
        left_fwd = duty(r.tccr0a, 0x20, r.ocr0b, r.portd, r.ddrd, 1 << 5)  # pin 5, OC0B
        right_back = duty(r.tccr0a, 0x80, r.ocr0a, r.portd, r.ddrd, 1 << 6)  # pin 6, OC0A
        right_fwd = duty(r.tccr2a, 0x80, r.ocr2a, r.portb, r.ddrb, 1 << 3)  # pin 11, OC2A
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
        # Any address: the image's UART carries its frames only (at the address a PROVISION may change).
        return FrameDecoder(
            None if self._key is None else Verifier(self._key, SIGN_ROVER_TO_HOST, require=False), address=None
        )

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
            worst = {
                "us": round((w[1] - w[0]) * us, 1),
                "t_s": round(self.start_ms / 1000 + w[0] / CLOCK_HZ, 4),
                "state": _state_name(w[2] & DESC_STATE_MASK) if w[3] else None,
                "flags": _flag_names(w[2]) if w[3] else None,
            }
        periods = [(b[0] - a[0]) * us for a, b in zip(records, records[1:]) if a[4] == b[4]]
        jitter = sorted(abs(p - STEP_US) for p in periods)
        simulated_s = s.cycle / CLOCK_HZ
        lowest = s.stack_lowest
        painted = s.paint_start and s.paint_start <= s.ramend
        stack = {
            "ram_end": f"0x{s.ramend:04X}",
            "static_end": f"0x{s.paint_start:04X}",
            "static_bytes": s.paint_start - 0x100,
            "used_bytes": (s.ramend + 1 - lowest) if painted else None,
            "margin_bytes": (lowest - s.paint_start) if painted else None,
            "lowest_address": f"0x{lowest:04X}" if painted else None,
        }
        return {
            "image": str(self.elf.relative_to(ROOT) if self.elf.is_relative_to(ROOT) else self.elf),
            "clock_hz": CLOCK_HZ,
            "hooks": {"step_probe_pb0": bool(records), "descriptor_gpior0": bool(with_desc)},
            "steps": len(records),
            "step_time": _summary(all_us),
            "by_state": {k: _summary(v) for k, v in sorted(by_state.items())},
            "by_flag": {k: _summary(v) for k, v in by_flag.items()},
            "worst_step": worst,
            "period_jitter": {
                "periods": len(periods),
                "mean_period_us": round(sum(periods) / len(periods), 1) if periods else None,
                "max_abs_us": round(jitter[-1], 1) if jitter else None,
                "p99_abs_us": round(_percentile(jitter, 99), 1) if jitter else None,
            },
            "stack": stack,
            "gyro": {
                "addressed": s.twi_addressed,
                "whoami_reads": s.twi_whoami_reads,
                "gyro_reads": s.twi_gyro_reads,
                "nacked": s.twi_nacked,
                "workarounds": {
                    "sla_w_status_fixed": s.twi_status_fixed,
                    "twint_cleared": s.twi_twint_cleared,
                    "twsto_cleared": s.twi_twsto_cleared,
                },
            },
            "sonar": {"pings": s.pings, "echoes": s.echoes, "ignored_while_busy": s.pings_ignored},
            "uart": {"bytes_in": s.uart_bytes_in, "bytes_out": s.uart_bytes_out, "xoff": s.uart_xoffs},
            "resets": s.resets,
            "speed": {
                "simulated_s": round(simulated_s, 3),
                "avr_wall_s": round(self.wall_s, 3),
                "avr_x_real_time": round(simulated_s / self.wall_s, 2) if self.wall_s > 0 else None,
                "idle_fast_forward_share": round(s.skipped_cycles / s.cycle, 3) if s.cycle else None,
            },
            **({"profile": self.profile()} if self._fmap is not None else {}),
        }

    def profile(self) -> dict:
        """uno_timing["profile"]: where the steps' cycles go (rovernav.cores.profile.read_profile);
        {} unless `enable_profile` was called."""
        if self._fmap is None:
            return {}
        if not getattr(self, "_h", None):
            return self._final_profile or {}
        return read_profile(self._lib, self._h, self._fmap)
