"""A fleet's run log (issue 30): one MCAP file, a channel set per rover.

What the camera sees and the arena are the fleet's, once (`/camera/image`, `/arena`, and the
simulator's `/events`); each rover's mission, link, sonar, map and poses are its own, the lone
rover's channels under `/rover1`, `/rover2`, ... (`/rover2/camera/fix`, `/rover2/plan/path`, ...).
The raw bytes are left out: the fleet's rovers share one radio, and a rover's frames are in its
decoded `/roverK/link/...` channels. `rovernav replay` takes a lone rover's log, not a fleet's.
"""

from __future__ import annotations

from pathlib import Path

from .channels import CHANNELS, DEFAULT_IMAGE_HZ
from .writer import RunLog

#: The fleet's own channels: one camera, one arena, the simulator's events.
SHARED_TOPICS = frozenset({"/camera/image", "/arena", "/events"})
#: Not in a fleet's log: the shared radio's raw bytes (and its counts), not one rover's.
LEFT_OUT_TOPICS = frozenset({"/link/raw/host_to_rover", "/link/raw/rover_to_host", "/sim/radio"})
#: Each rover's channels, under /roverK.
ROVER_TOPICS = frozenset(c.topic for c in CHANNELS) - LEFT_OUT_TOPICS - {"/camera/image", "/arena"}


def rover_prefix(k: int) -> str:
    """Rover k's (0-based) channels' prefix: /rover1 for the first."""
    return f"/rover{k + 1}"


class FleetRunLog:
    """The run log of a fleet: `shared` (the file, the camera, the arena, the simulator's events)
    and `rovers[k]`, rover k's channel set, the recorder of its mission."""

    def __init__(
        self,
        path: str | Path | None,
        specs: list,
        *,
        source: str,
        scenario=None,
        truth: bool = False,
        image_hz: float = DEFAULT_IMAGE_HZ,
        meta: dict | None = None,
    ):
        meta = {**(meta or {}), "rovers": len(specs), "rover_specs": [s.to_json() for s in specs]}
        self.shared = RunLog(
            path,
            specs[0],
            source=source,
            scenario=scenario,
            truth=truth,
            image_hz=image_hz,
            meta=meta,
            topics=set(SHARED_TOPICS),
        )
        self.rovers = [
            RunLog(
                None,
                spec,
                source=source,
                truth=truth,
                context=self.shared.ctx,
                topic_prefix=rover_prefix(k),
                topics=set(ROVER_TOPICS),
                t0_ns=self.shared.t0_ns,
            )
            for k, spec in enumerate(specs)
        ]

    @property
    def path(self) -> Path | None:
        return self.shared.path

    def set_time(self, t_s: float) -> None:
        self.shared.set_time(t_s)
        for r in self.rovers:
            r.set_time(t_s)

    def camera_image(self, t_s: float, frame_bgr) -> None:
        """A camera frame, in the fleet's one camera channel (kept when the image rate allows)."""
        self.shared.camera_image(t_s, frame_bgr)

    def close(self, summary: dict | None = None) -> None:
        """The rovers' last driven paths, then the file closed and renamed into place."""
        for r in self.rovers:
            r.close()
        self.shared.close(summary)
