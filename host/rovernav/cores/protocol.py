"""What a rover core is to the simulator and the tests: the `RoverCore` protocol.

Two implementations step the same firmware:

- `rovernav.cores.native.NativeCore`: the core compiled for this machine, behind its C ABI
  (firmware/abi/rover_abi.h), one call per step;
- `rovernav.cores.uno.UnoCore`: the Uno image itself, run in simavr up to each step's time,
  its outputs read off the AVR's pins.

Both take one tick of sensor readings and received bytes and give back what the rover asked
for (`StepOut`), and both offer the core's internal state for reports (`Probe`).
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

from ..errors import SetupError


class FirmwareBuildError(SetupError):
    """A rover core could not be built or loaded (the native library, or the Uno image and its harness)."""


@dataclasses.dataclass(frozen=True)
class StepOut:
    """What the rover asked for in one step."""

    left_pwm: int
    right_pwm: int
    servo_cdeg: int
    fire_sonar: bool
    tx: bytes


@dataclasses.dataclass(frozen=True)
class Probe:
    """The core's internal state, for reports and pictures only: never fed back to the host."""

    state: int
    fault: int
    flags: int
    waypoint_index: int
    waypoint_count: int
    x_mm: float
    y_mm: float
    heading_rad: float
    position_sd_mm: float
    speed_scale: float
    dr_distance_mm: float


@runtime_checkable
class RoverCore(Protocol):
    """One rover's firmware, stepped by its caller's clock. Not thread-safe: step it from one thread.

    The contract both implementations keep:

    - `step()` is called with a non-decreasing `now_ms`, once per 10 ms tick of the caller; what it
      returns is what the rover's outputs are at `now_ms`, and they hold until the next step.
    - `probe()` is for reports and pictures only: nothing it says may be fed back to the rover.
    - `close()` frees the core; it may be called more than once. A closed core is not stepped again.
    """

    def step(
        self,
        now_ms: int,
        *,
        gyro_rate_mdps: int | None,
        sonar_range_mm: int | None = None,
        rx: bytes = b"",
        tx_room: int = ...,
        wheel_ticks: tuple[int, int] | None = None,
    ) -> StepOut:
        """One tick at `now_ms` (ms since the caller's start, wrapped to 32 bits by the core).

        gyro_rate_mdps: the gyro's yaw rate, clockwise [mdeg/s]; None: no sample this tick (the
        chip does not answer). sonar_range_mm: the range of the ping the core asked for at the
        last step (`StepOut.fire_sonar`), 0 for no echo, None for no result this tick. rx: the
        bytes the radio delivered since the last step. tx_room: how many bytes the serial line can
        take now. wheel_ticks: encoder counts since the last step, None without encoders.
        An implementation that measures a reading itself (the Uno image pings its own sonar
        model) says which of these it ignores."""
        ...

    def probe(self) -> Probe:
        """The core's state now (its mission state, fault, pose estimate and its uncertainty)."""
        ...

    def auth_counters(self) -> dict[str, int]:
        """Frames the rover refused for their signature, by reason: bad_tag, replayed,
        not_signed, unverified."""
        ...

    def close(self) -> None:
        """Free the core (idempotent)."""
        ...
