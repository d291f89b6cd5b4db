"""A test helper: the rover's firmware core (its C ABI) behind a Transport, in simulated time.
Used by the provisioning, Uno, run-log, mission and lossy-exchange tests."""

from __future__ import annotations

from rovernav.cores import NativeCore
from rovernav.link import framing
from rovernav.link import messages_gen as mg
from rovernav.link.transport import Transport


class CoreTransport(Transport):
    """The rover core behind a serial port: a read steps it for the time the read may wait."""

    def __init__(self, core: NativeCore):
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

    core = NativeCore(boot_id=1)
    try:
        frames = framing.FrameDecoder().feed(core.step(0, gyro_rate_mdps=0).tx)
    finally:
        core.close()
    hello = next(f.message for f in frames if isinstance(f.message, mg.Hello))
    return dataclasses.replace(hello, **changes)


class CoreRover:
    """The rover's firmware core behind one end of a pipe, stepped every 10 ms up to the time it is served.
    It stands still (nothing moves it), so sonar reports and arrivals a test needs are said for it
    (`say`). What the host sent is kept, decoded, for the test to look at."""

    def __init__(self, end, boot_id=11):
        self.end, self.core, self.t_ms = end, NativeCore(boot_id=boot_id), 0
        self.decoder = framing.FrameDecoder()
        self.got: list = []
        self.said: list = []  # what the rover itself sent, decoded
        self._out = framing.FrameDecoder()
        self.seq = 128  # frames said for the rover, numbered apart from its own

    def serve(self, t_s):
        data = self.end.read(65536, 0)
        self.got += [f.message for f in self.decoder.feed(data)]
        while self.t_ms <= t_s * 1000:
            out = self.core.step(self.t_ms, gyro_rate_mdps=0, rx=data)
            data = b""
            if out.tx:
                self.said += [f.message for f in self._out.feed(out.tx)]
                self.end.write(out.tx)
            self.t_ms += 10

    def reboot(self, boot_id):
        self.core.close()
        self.core = NativeCore(boot_id=boot_id, reset_cause=4)

    def say(self, m):
        self.end.write(framing.encode_frame(m, self.seq))
        self.seq = (self.seq + 1) & 0xFF

    def of(self, cls):
        return [m for m in self.got if isinstance(m, cls)]

    @property
    def paths(self) -> dict[int, list]:
        out: dict[int, list] = {}
        for m in self.of(mg.Path):
            out.setdefault(m.path_id, {})[m.first_index] = [
                (m.x_mm[i] / 1000, m.y_mm[i] / 1000) for i in range(m.count)
            ]
        return {k: [p for first in sorted(v) for p in v[first]] for k, v in out.items()}

    @property
    def state(self) -> int:
        return self.core.probe().state


class FleetCoreTransport(Transport):
    """A fleet's rover cores behind one radio: what the host writes reaches every core; a read
    steps them all (as CoreTransport steps one) and returns what they said, rover after rover."""

    def __init__(self, cores: list):
        super().__init__("fleet-core://")
        self.cores, self.t_ms, self.to_rovers, self.from_rovers = cores, 0, b"", b""

    def _write(self, data: bytes) -> None:
        self.to_rovers += data

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        if not self.from_rovers:
            for _ in range(max(1, int((timeout_s or 0.0) * 100))):
                rx, self.to_rovers = self.to_rovers, b""
                for core in self.cores:
                    self.from_rovers += core.step(self.t_ms, gyro_rate_mdps=0, rx=rx).tx
                self.t_ms += 10
        data, self.from_rovers = self.from_rovers[:max_bytes], self.from_rovers[max_bytes:]
        return data

    def _close(self) -> None:
        pass
