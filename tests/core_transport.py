"""A test helper: the rover's firmware core (its C ABI) behind a Transport, in simulated time.
Used by the provisioning, Uno and run-log tests."""
from __future__ import annotations

from rovernav.firmware import RoverCore
from rovernav.link.transport import Transport


class CoreTransport(Transport):
    """The rover core behind a serial port: a read steps it for the time the read may wait."""

    def __init__(self, core: RoverCore):
        super().__init__("core://")
        self.core, self.t_ms, self.to_rover, self.from_rover = core, 0, b"", b""
        self.sent_to_rover = b""

    def run_ms(self, ms: int) -> None:
        for _ in range(ms // 10):
            out = self.core.step(self.t_ms, gyro_rate_mdps=0, rx=self.to_rover)
            self.to_rover = b""
            self.from_rover += out.tx
            self.t_ms += 10

    def clock(self) -> float:
        return self.t_ms / 1000.0

    def _write(self, data: bytes) -> None:
        self.to_rover += data
        self.sent_to_rover += data

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        if not self.from_rover:
            self.run_ms(max(10, int((timeout_s or 0.0) * 1000)))
        data, self.from_rover = self.from_rover[:max_bytes], self.from_rover[max_bytes:]
        return data

    def _close(self) -> None:
        pass


def firmware_hello(**changes):
    """The HELLO the firmware core itself says at boot (its version, its waypoint capacity), with
    `changes` (another schema, boot id, ...) for a stand-in rover to say."""
    import dataclasses

    from rovernav.link import framing
    from rovernav.link import messages_gen as mg

    core = RoverCore(boot_id=1)
    try:
        frames = framing.FrameDecoder().feed(core.step(0, gyro_rate_mdps=0).tx)
    finally:
        core.close()
    hello = next(f.message for f in frames if isinstance(f.message, mg.Hello))
    return dataclasses.replace(hello, **changes)
