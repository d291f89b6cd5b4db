"""What a mission tells a run log: the `Recorder` interface, here doing nothing."""

from __future__ import annotations

from ..mapping import LearnedMap, SonarReading


class Recorder:
    """What a mission tells a run log (rovernav.runlog.RunLog), here doing nothing.

    Inputs, in the order they reach the mission: the ticks, the camera's detections, every frame
    it takes from the rover, and a failure imposed from outside; `rovernav replay` feeds these to
    a new Mission and compares its outputs: the frames it sends (and the events it reports)."""

    def host_input(self, kind: str, t_s: float, **data) -> None:
        pass

    def host_rx(self, t_s: float, frame) -> None:
        pass

    def host_tx(self, t_s: float, message, seq: int) -> None:
        pass

    def host_event(self, t_s: float, text: str) -> None:
        pass

    def host_path(self, t_s: float, path_id: int, path: list[tuple[float, float]]) -> None:
        pass

    def host_sonar(self, t_s: float, reading: SonarReading, changed: bool) -> None:
        pass

    def host_map(self, t_s: float, learned_map: LearnedMap) -> None:
        pass

    def host_link(self, t_s: float, quality: dict) -> None:
        """Frames through both ways (recent and whole-run) and frames sent again: once a second."""
