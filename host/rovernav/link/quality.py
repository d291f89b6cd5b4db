"""How well the radio carries frames, both ways, measured by the host from what it already hears.

Rover to host: every frame the rover sends carries its sequence number (0..255, wrapping), so a
gap between two frames the host took is frames lost (or refused: broken on the way). Host to
rover: the rover counts the valid frames it received (STATUS.rx_ok, 16 bits, wrapping) and the
broken ones (bad CRC, malformed, overlong); between two STATUS the host knows how many frames
it sent. So both rates come from the link as it is, with nothing more on the air.

Rates are kept over the whole run and over a recent window (`window_s`), as shares of frames
that arrived whole. A rover that restarts (a new boot id) starts its counters again: `restart()`.
A gap longer than `max_gap_s` between two rover frames is an outage, not loss the sequence
numbers can count (they wrap after 256 frames): it is left out of the rate, and the outage is
what the mission reports instead.
"""

from __future__ import annotations

import collections
import dataclasses

from . import messages_gen as mg


@dataclasses.dataclass
class Direction:
    """Frames one way: sent, and of those, arrived whole."""

    sent: int = 0
    arrived: int = 0

    @property
    def rate(self) -> float | None:
        """Share of frames that arrived whole (None before any was sent)."""
        return None if self.sent <= 0 else min(1.0, self.arrived / self.sent)

    def add(self, sent: int, arrived: int) -> None:
        self.sent += sent
        self.arrived += arrived


class LinkQuality:
    """Frame success both ways; see the module docstring."""

    def __init__(self, window_s: float = 10.0, max_gap_s: float = 5.0) -> None:
        self.window_s = window_s
        self.max_gap_s = max_gap_s
        self.to_rover = Direction()  # the whole run
        self.to_host = Direction()
        self.rover_broken = 0  # frames the rover received broken (bad CRC, malformed, overlong)
        self._recent: collections.deque[tuple[float, str, int, int]] = collections.deque()
        self._last_seq: int | None = None
        self._last_rx_s: float | None = None
        self._last_status: tuple[int, int, int] | None = None  # rover rx_ok, rover broken, host sent

    def restart(self) -> None:
        """The rover restarted: its sequence numbers and counters start again."""
        self._last_seq = None
        self._last_status = None

    def on_frame(self, seq: int, now_s: float) -> None:
        """A frame from the rover arrived whole, numbered `seq`."""
        if self._last_seq is not None and self._last_rx_s is not None and now_s - self._last_rx_s <= self.max_gap_s:
            lost = (seq - self._last_seq - 1) & 0xFF
            self._count("to_host", lost + 1, 1, now_s)
        self._last_seq = seq
        self._last_rx_s = now_s

    def on_status(self, status: mg.Status, host_sent: int, now_s: float) -> None:
        """A STATUS arrived; `host_sent`: frames the host has sent so far."""
        broken = status.rx_bad_crc + status.rx_malformed + status.rx_overlong
        if self._last_status is not None:
            ok0, broken0, sent0 = self._last_status
            got = (status.rx_ok - ok0) & 0xFFFF
            sent = host_sent - sent0
            # Frames still on the air when the STATUS left are counted in the next interval (so
            # one interval may count more arrived than sent: the sums even out; rates clamp at 1).
            if sent > 0 or got > 0:
                self._count("to_rover", sent, got, now_s)
            self.rover_broken += (broken - broken0) & 0xFFFF
        self._last_status = (status.rx_ok, broken, host_sent)

    def _count(self, which: str, sent: int, arrived: int, now_s: float) -> None:
        getattr(self, which).add(sent, arrived)
        self._recent.append((now_s, which, sent, arrived))
        while self._recent and now_s - self._recent[0][0] > self.window_s:
            self._recent.popleft()

    def recent(self, which: str) -> float | None:
        """Share of frames that arrived whole in the last window_s ('to_rover' or 'to_host')."""
        d = Direction()
        for _, w, sent, arrived in self._recent:
            if w == which:
                d.add(sent, arrived)
        return d.rate

    def summary(self) -> dict:
        """For report.json and the run log."""

        def one(d: Direction) -> dict:
            return {
                "frames_sent": d.sent,
                "frames_arrived": d.arrived,
                "success": None if d.rate is None else round(d.rate, 4),
            }

        return {
            "host_to_rover": one(self.to_rover),
            "rover_to_host": one(self.to_host),
            "rover_received_broken": self.rover_broken,
        }

    def line(self) -> str:
        """For a status line: 'link up 98.7 % down 99.1 %' over the recent window."""

        def pct(v: float | None) -> str:
            return "-" if v is None else f"{100 * v:.1f} %"

        return f"frames through: to rover {pct(self.recent('to_rover'))}, from rover {pct(self.recent('to_host'))}"
